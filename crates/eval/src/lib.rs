//! Middlebury-style accuracy metrics of a disparity map against ground truth.
