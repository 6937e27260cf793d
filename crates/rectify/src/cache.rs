//! One [`Rectifier`] per image size, made on first use and shared: a batch of pairs from one
//! calibration computes its maps once.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::calib_file::StereoCalibration;
use crate::stereo::Rectifier;

/// The rectifiers of one calibration, by image size.
#[derive(Debug)]
pub struct RectifierCache {
    calibration: Arc<StereoCalibration>,
    alpha: f64,
    made: Mutex<HashMap<(usize, usize), Arc<Rectifier>>>,
    computed: std::sync::atomic::AtomicUsize,
}

impl RectifierCache {
    pub fn new(calibration: Arc<StereoCalibration>, alpha: f64) -> Self {
        RectifierCache { calibration, alpha, made: Mutex::default(), computed: Default::default() }
    }

    pub fn calibration(&self) -> &StereoCalibration {
        &self.calibration
    }

    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// The rectifier for `size`, computed the first time (callers asking meanwhile wait for it
    /// rather than compute it again).
    pub fn get(&self, size: (usize, usize)) -> Result<Arc<Rectifier>, String> {
        let mut made = self.made.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(r) = made.get(&size) {
            return Ok(Arc::clone(r));
        }
        let rectifier = Arc::new(Rectifier::new(&self.calibration, size, self.alpha)?);
        self.computed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        made.insert(size, Arc::clone(&rectifier));
        Ok(rectifier)
    }

    /// How many times maps were computed (once per image size).
    pub fn computed(&self) -> usize {
        self.computed.load(std::sync::atomic::Ordering::Relaxed)
    }
}
