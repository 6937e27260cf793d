//! The image-loading path (format detection, header check against the pixel limit, decoding,
//! conversion to grey) on arbitrary bytes: an error or an image within the limit, never a panic
//! and never a decode of a declared size over the limit.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

/// Small, so a lying header cannot make the fuzzer allocate gigabytes.
const MAX_PIXELS: u64 = 1 << 20;

fuzz_target!(|data: &[u8]| {
    if let Ok(image) = stereo_io::decode_gray(data, Path::new("fuzz.png"), MAX_PIXELS) {
        let (w, h) = image.size();
        assert!(w > 0 && h > 0 && (w * h) as u64 <= MAX_PIXELS, "{w}x{h}");
    }
});
