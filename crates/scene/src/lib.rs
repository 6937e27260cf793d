//! Synthetic rectified stereo scenes with exact ground-truth disparity.
