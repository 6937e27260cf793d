//! The Middlebury calib.txt parser on arbitrary text: an error message or a calibration with
//! finite numbers, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match stereo_io::parse_calib(text) {
        Ok(calib) => {
            for v in [calib.focal_px, calib.cx, calib.cy] {
                assert!(v.is_finite(), "{calib:?}");
            }
            for v in [calib.doffs, calib.baseline_mm].into_iter().flatten() {
                assert!(v.is_finite(), "{calib:?}");
            }
        }
        Err(message) => assert!(!message.is_empty()),
    }
});
