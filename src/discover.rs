//! Pair discovery lives in the `stereo-discover` crate (pure functions over a file list), so the
//! fuzz targets can link it; this module keeps the binary's `crate::discover` paths.

pub use stereo_discover::*;
