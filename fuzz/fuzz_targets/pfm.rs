//! The PFM reader on arbitrary bytes: an error or a map whose size matches its header, never a
//! panic or an allocation beyond the input's size.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(map) = stereo_io::decode_pfm(data, Path::new("fuzz.pfm")) {
        let (w, h) = map.size();
        assert!(w > 0 && h > 0);
        assert!(w * h * 4 <= data.len(), "{w}x{h} from {} bytes", data.len());
        // What is read writes back and reads again bit-exact.
        let again = stereo_io::decode_pfm(&stereo_io::encode_pfm(&map), Path::new("again.pfm")).unwrap();
        let bits = |s: &[f32]| s.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(map.as_slice()), bits(again.as_slice()));
    }
});
