//! Integration tests of stereo-io: PFM, PNG/PNM loading, ground truth, EXR, atomic writes.

use std::path::{Path, PathBuf};

use image::{ImageBuffer, Luma, LumaA, Rgb, Rgba};
use stereo_image::Image;
use stereo_io::{
    exr_channel_names, load_gray, load_rgb8, read_disparity, read_exr_channel, read_pfm, write_atomic,
    write_exr, write_pfm, Error,
};

fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// Asserts a Format error whose message names the file and contains `needle`.
#[track_caller]
fn assert_format_err<T: std::fmt::Debug>(result: Result<T, Error>, path: &Path, needle: &str) {
    let err = result.expect_err("expected an error");
    let text = err.to_string();
    assert!(matches!(err, Error::Format { .. }), "not a Format error: {text}");
    assert_names_file(&text, path);
    assert!(text.contains(needle), "{text:?} does not contain {needle:?}");
    assert!(!text.contains('\n'), "multi-line message {text:?}");
}

#[track_caller]
fn assert_names_file(text: &str, path: &Path) {
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(text.contains(name), "{text:?} does not name {name}");
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn bits(image: &Image<f32>) -> Vec<u32> {
    image.as_slice().iter().map(|v| v.to_bits()).collect()
}

// ---------------------------------------------------------------------------------------------
// PFM

#[test]
fn pfm_round_trip_is_bit_exact_and_bottom_to_top() {
    let dir = tempdir();
    let path = dir.path().join("disp.pfm");
    let payload_nan = f32::from_bits(0x7fc0_1234);
    let map = Image::from_vec(3, 2, vec![1.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, payload_nan])
        .unwrap();
    write_pfm(&path, &map).unwrap();

    let raw = std::fs::read(&path).unwrap();
    let header = b"Pf\n3 2\n-1.0\n";
    assert_eq!(&raw[..header.len()], header);
    assert_eq!(raw.len(), header.len() + 6 * 4);
    // The first stored row is the last image row, little endian.
    let first_row: Vec<u8> = map.row(1).iter().flat_map(|v| v.to_le_bytes()).collect();
    assert_eq!(&raw[header.len()..header.len() + 12], &first_row[..]);
    let last_row: Vec<u8> = map.row(0).iter().flat_map(|v| v.to_le_bytes()).collect();
    assert_eq!(&raw[header.len() + 12..], &last_row[..]);

    let back = read_pfm(&path).unwrap();
    assert_eq!(back.size(), (3, 2));
    assert_eq!(bits(&back), bits(&map));
    assert_eq!(files_in(dir.path()), vec!["disp.pfm"]);
}

#[test]
fn pfm_reads_big_endian_and_tolerant_headers() {
    let dir = tempdir();
    // 2x2, big endian (positive scale), rows bottom to top: stored [3, 4] then [1, 2].
    let mut bytes = b"Pf\n# written by a test\n2   2\r\n1.0\n".to_vec();
    for v in [3.0f32, 4.0, 1.0, 2.0] {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    let path = dir.path().join("be.pfm");
    std::fs::write(&path, &bytes).unwrap();
    let map = read_pfm(&path).unwrap();
    assert_eq!(map.as_slice(), &[1.0, 2.0, 3.0, 4.0]);

    // Header on one line, little endian with a non-unit scale; trailing bytes are ignored.
    let mut bytes = b"Pf 1 2 -0.5\n".to_vec();
    for v in [7.0f32, 8.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(b"junk");
    let path = dir.path().join("le.pfm");
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(read_pfm(&path).unwrap().as_slice(), &[8.0, 7.0]);
}

#[test]
fn malformed_pfms_are_format_errors() {
    let dir = tempdir();
    let data16 = [0u8; 16];
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("magic.pfm", [b"P6\n2 2\n-1\n".as_slice(), &data16].concat(), "not a PFM file"),
        ("colour.pfm", [b"PF\n2 2\n-1\n".as_slice(), &[0u8; 48]].concat(), "colour PFM"),
        ("short.pfm", [b"Pf\n10 30\n-1\n".as_slice(), &[0u8; 600]].concat(), "expected 1200 bytes"),
        ("huge.pfm", [b"Pf\n100000 100000\n-1\n".as_slice(), &data16].concat(), "truncated PFM data"),
        (
            "overflow.pfm",
            [b"Pf\n9223372036854775807 9223372036854775807\n-1\n".as_slice(), &data16].concat(),
            "truncated PFM data",
        ),
        ("negative.pfm", [b"Pf\n-2 2\n-1\n".as_slice(), &data16].concat(), "bad PFM size"),
        ("zero.pfm", [b"Pf\n0 2\n-1\n".as_slice(), &data16].concat(), "bad PFM size"),
        ("scale0.pfm", [b"Pf\n2 2\n0\n".as_slice(), &data16].concat(), "bad PFM scale"),
        ("words.pfm", [b"Pf\ntwo 2\n-1\n".as_slice(), &data16].concat(), "bad PFM header"),
        ("garbage.pfm", b"hello world, this is not a float map\n".to_vec(), "not a PFM file"),
        ("longtoken.pfm", vec![b'x'; 200], "too long"),
        ("header.pfm", b"Pf\n2 2\n".to_vec(), "truncated PFM header"),
        ("empty.pfm", Vec::new(), "empty file"),
    ];
    for (name, bytes, needle) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        assert_format_err(read_pfm(&path), &path, needle);
    }
}

#[test]
fn pfm_missing_file_and_directory_are_io_errors() {
    let dir = tempdir();
    let missing = dir.path().join("missing.pfm");
    let err = read_pfm(&missing).unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert_names_file(&err.to_string(), &missing);
    assert!(read_pfm(dir.path()).is_err());
}

#[test]
fn write_pfm_rejects_empty_images() {
    let dir = tempdir();
    let path = dir.path().join("empty.pfm");
    assert_format_err(write_pfm(&path, &Image::new(0, 3, 0.0)), &path, "empty image");
    assert!(files_in(dir.path()).is_empty());
}

// ---------------------------------------------------------------------------------------------
// PNG / PNM

fn save<P, C>(dir: &Path, name: &str, image: &ImageBuffer<P, C>) -> PathBuf
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let path = dir.join(name);
    image.save(&path).unwrap();
    path
}

#[test]
fn load_gray_from_8_and_16_bit_grey() {
    let dir = tempdir();
    let g8 = ImageBuffer::from_fn(3, 2, |x, y| Luma([if (x, y) == (1, 1) { 200u8 } else { 0 }]));
    let path = save(dir.path(), "g8.png", &g8);
    let img = load_gray(&path).unwrap();
    assert_eq!(img.size(), (3, 2));
    assert_eq!(img.get(1, 1), 51400);
    assert_eq!(img.get(0, 0), 0);

    let g16 = ImageBuffer::from_fn(3, 2, |x, y| Luma([1000u16 + x as u16 + 10 * y as u16]));
    let path = save(dir.path(), "g16.png", &g16);
    let img = load_gray(&path).unwrap();
    assert_eq!(img.get(0, 0), 1000);
    assert_eq!(img.get(2, 1), 1012);

    let la8 = ImageBuffer::from_pixel(2, 2, LumaA([200u8, 7]));
    let path = save(dir.path(), "la8.png", &la8);
    assert_eq!(load_gray(&path).unwrap().as_slice(), &[51400; 4]);

    // 16-bit PGM, detected from content even with a misleading extension.
    let path = dir.path().join("g16.pgm");
    g16.save_with_format(&path, image::ImageFormat::Pnm).unwrap();
    assert_eq!(load_gray(&path).unwrap().get(2, 1), 1012);
    let renamed = dir.path().join("really_pgm.png");
    std::fs::rename(&path, &renamed).unwrap();
    assert_eq!(load_gray(&renamed).unwrap().get(2, 1), 1012);
}

#[test]
fn load_gray_converts_colour_with_rec601() {
    let dir = tempdir();
    let rgb8 = ImageBuffer::from_fn(3, 1, |x, _| {
        Rgb(match x {
            0 => [255u8, 0, 0],
            1 => [200, 200, 200],
            _ => [0, 0, 255],
        })
    });
    let path = save(dir.path(), "rgb8.png", &rgb8);
    // 0.299 * 65535 = 19594.97; 0.114 * 65535 = 7470.99.
    assert_eq!(load_gray(&path).unwrap().as_slice(), &[19595, 51400, 7471]);

    let rgba8 = ImageBuffer::from_pixel(2, 1, Rgba([200u8, 200, 200, 0]));
    let path = save(dir.path(), "rgba8.png", &rgba8);
    assert_eq!(load_gray(&path).unwrap().as_slice(), &[51400, 51400]);

    let rgb16 = ImageBuffer::from_fn(2, 1, |x, _| {
        Rgb(if x == 0 { [1000u16, 1000, 1000] } else { [1000, 2000, 3000] })
    });
    let path = save(dir.path(), "rgb16.png", &rgb16);
    // 0.299 * 1000 + 0.587 * 2000 + 0.114 * 3000 = 1815.
    assert_eq!(load_gray(&path).unwrap().as_slice(), &[1000, 1815]);

    let rgba16 = ImageBuffer::from_pixel(1, 1, Rgba([1001u16, 1001, 1001, 65535]));
    let path = save(dir.path(), "rgba16.png", &rgba16);
    assert_eq!(load_gray(&path).unwrap().as_slice(), &[1001]);
}

#[test]
fn load_rgb8_keeps_colour() {
    let dir = tempdir();
    let rgb16 = ImageBuffer::from_pixel(1, 1, Rgb([0x1234u16, 0xabcd, 0x00ff]));
    let path = save(dir.path(), "rgb16.png", &rgb16);
    assert_eq!(load_rgb8(&path).unwrap().as_slice(), &[[0x12, 0xab, 0x00]]);

    let g8 = ImageBuffer::from_pixel(2, 1, Luma([77u8]));
    let path = save(dir.path(), "g8.png", &g8);
    assert_eq!(load_rgb8(&path).unwrap().as_slice(), &[[77, 77, 77]; 2]);

    let rgba8 = ImageBuffer::from_pixel(1, 1, Rgba([1u8, 2, 3, 4]));
    let path = save(dir.path(), "rgba8.png", &rgba8);
    assert_eq!(load_rgb8(&path).unwrap().as_slice(), &[[1, 2, 3]]);
}

#[test]
fn bad_images_are_errors_naming_the_file() {
    let dir = tempdir();
    let text = dir.path().join("left.png");
    std::fs::write(&text, b"this is a text file, not a picture").unwrap();
    assert_format_err(load_gray(&text), &text, "not a PNG image");
    assert_format_err(load_rgb8(&text), &text, "not a PNG image");

    let other = dir.path().join("notes.txt");
    std::fs::write(&other, b"hello").unwrap();
    assert_format_err(load_gray(&other), &other, "unrecognised format");

    let empty = dir.path().join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    assert_format_err(load_gray(&empty), &empty, "empty file");

    let good = ImageBuffer::from_fn(64, 64, |x, y| Luma([(x * 7 + y * 13) as u8]));
    let path = save(dir.path(), "good.png", &good);
    let bytes = std::fs::read(&path).unwrap();
    let truncated = dir.path().join("truncated.png");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let err = load_gray(&truncated).unwrap_err();
    assert!(matches!(err, Error::Format { .. }), "{err}");
    assert_names_file(&err.to_string(), &truncated);

    let header_only = dir.path().join("header_only.png");
    std::fs::write(&header_only, &bytes[..20]).unwrap();
    let err = load_gray(&header_only).unwrap_err();
    assert_names_file(&err.to_string(), &header_only);

    assert_format_err(load_gray(dir.path()), dir.path(), "directory");

    let missing = dir.path().join("missing.png");
    let err = load_gray(&missing).unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert_names_file(&err.to_string(), &missing);
}

// ---------------------------------------------------------------------------------------------
// Ground truth

#[test]
fn read_disparity_png_divides_by_scale_and_zero_is_unknown() {
    let dir = tempdir();
    let values = [0u16, 4, 10, 1000];
    let g16 = ImageBuffer::from_fn(4, 1, |x, _| Luma([values[x as usize]]));
    let path = save(dir.path(), "disp16.png", &g16);
    let d = read_disparity(&path, 4.0).unwrap();
    assert!(d.get(0, 0).is_nan());
    assert_eq!(&d.as_slice()[1..], &[1.0, 2.5, 250.0]);

    let g8 = ImageBuffer::from_fn(2, 1, |x, _| Luma([x as u8 * 200]));
    let path = save(dir.path(), "disp8.png", &g8);
    let d = read_disparity(&path, 4.0).unwrap();
    assert!(d.get(0, 0).is_nan());
    assert_eq!(d.get(1, 0), 50.0);

    let pgm = dir.path().join("disp.pgm");
    g16.save_with_format(&pgm, image::ImageFormat::Pnm).unwrap();
    assert_eq!(read_disparity(&pgm, 2.0).unwrap().get(3, 0), 500.0);

    let grey_rgb = ImageBuffer::from_fn(2, 1, |x, _| Rgb([x as u8 * 8; 3]));
    let path = save(dir.path(), "grey_rgb.png", &grey_rgb);
    assert_eq!(read_disparity(&path, 4.0).unwrap().get(1, 0), 2.0);

    let colour = ImageBuffer::from_pixel(2, 1, Rgb([1u8, 2, 3]));
    let path = save(dir.path(), "colour.png", &colour);
    assert_format_err(read_disparity(&path, 4.0), &path, "channels differ");

    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert_format_err(read_disparity(&pgm, bad), &pgm, "scale");
    }
    let unknown = dir.path().join("disp.bmp");
    std::fs::write(&unknown, b"BM").unwrap();
    assert_format_err(read_disparity(&unknown, 1.0), &unknown, "unknown disparity format");
}

#[test]
fn read_disparity_pfm_marks_non_positive_and_non_finite_unknown() {
    let dir = tempdir();
    let path = dir.path().join("gt.PFM");
    let map = Image::from_vec(5, 1, vec![2.5, 0.0, -1.0, f32::INFINITY, f32::NAN]).unwrap();
    write_pfm(&path, &map).unwrap();
    let d = read_disparity(&path, 1.0).unwrap();
    assert_eq!(d.get(0, 0), 2.5);
    assert!(d.as_slice()[1..].iter().all(|v| v.is_nan()));
}

// ---------------------------------------------------------------------------------------------
// EXR

#[test]
fn exr_round_trip_through_the_exr_crate() {
    let dir = tempdir();
    let path = dir.path().join("depth.exr");
    let depth =
        Image::from_fn(7, 5, |x, y| if x == 3 && y == 2 { f32::NAN } else { 0.25 * (x + 7 * y) as f32 });
    write_exr(&path, &[("Z", &depth)]).unwrap();
    assert_eq!(files_in(dir.path()), vec!["depth.exr"]);

    // Read with the exr crate directly.
    let image = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
    let layer = &image.layer_data;
    assert_eq!((layer.size.width(), layer.size.height()), (7, 5));
    assert_eq!(layer.encoding.compression, exr::prelude::Compression::Uncompressed);
    let channels = &layer.channel_data.list;
    assert_eq!(channels.len(), 1);
    assert_eq!(channels[0].name.to_string(), "Z");
    let exr::prelude::FlatSamples::F32(samples) = &channels[0].sample_data else {
        panic!("Z is not f32");
    };
    for (a, b) in samples.iter().zip(depth.as_slice()) {
        assert!(a == b || (a.is_nan() && b.is_nan()), "{a} != {b}");
    }
    assert_eq!(samples.len(), 35);

    // And with our reader.
    let back = read_exr_channel(&path, "Z").unwrap();
    assert_eq!(back.size(), (7, 5));
    assert!(back.get(3, 2).is_nan());
    assert_eq!(back.get(6, 4), depth.get(6, 4));
    assert_eq!(exr_channel_names(&path).unwrap(), vec!["Z"]);
}

#[test]
fn exr_channels_are_found_by_name() {
    let dir = tempdir();
    let path = dir.path().join("multi.exr");
    let z = Image::new(4, 3, 2.0f32);
    let conf = Image::from_fn(4, 3, |x, y| (x * y) as f32);
    let a = Image::new(4, 3, -1.0f32);
    write_exr(&path, &[("Z", &z), ("confidence", &conf), ("A", &a)]).unwrap();
    let mut names = exr_channel_names(&path).unwrap();
    names.sort();
    assert_eq!(names, vec!["A", "Z", "confidence"]);
    assert_eq!(read_exr_channel(&path, "Z").unwrap(), z);
    assert_eq!(read_exr_channel(&path, "confidence").unwrap(), conf);
    assert_eq!(read_exr_channel(&path, "A").unwrap(), a);
    assert_format_err(read_exr_channel(&path, "Y"), &path, "no EXR channel \"Y\"");
}

#[test]
fn exr_errors() {
    let dir = tempdir();
    let path = dir.path().join("bad.exr");
    let small = Image::new(2, 2, 1.0f32);
    let big = Image::new(3, 2, 1.0f32);
    assert_format_err(write_exr(&path, &[]), &path, "without channels");
    assert_format_err(write_exr(&path, &[("Z", &small), ("W", &big)]), &path, "is 3x2");
    assert_format_err(write_exr(&path, &[("Z", &small), ("Z", &small)]), &path, "duplicate");
    assert_format_err(write_exr(&path, &[("", &small)]), &path, "channel name");
    assert_format_err(write_exr(&path, &[("Z", &Image::new(0, 0, 0.0))]), &path, "empty image");
    assert!(files_in(dir.path()).is_empty());

    std::fs::write(&path, b"not an exr file at all").unwrap();
    assert_format_err(read_exr_channel(&path, "Z"), &path, "EXR");
    assert_format_err(exr_channel_names(&path), &path, "EXR");
    let missing = dir.path().join("missing.exr");
    let err = read_exr_channel(&missing, "Z").unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert_names_file(&err.to_string(), &missing);
}

// ---------------------------------------------------------------------------------------------
// Atomic writes

#[test]
fn write_atomic_replaces_and_leaves_no_temporaries() {
    let dir = tempdir();
    let path = dir.path().join("out.bin");
    write_atomic(&path, b"first").unwrap();
    write_atomic(&path, b"second, longer").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"second, longer");
    assert_eq!(files_in(dir.path()), vec!["out.bin"]);
}

#[test]
fn write_atomic_fails_cleanly() {
    let dir = tempdir();
    let missing = dir.path().join("no_such_folder").join("out.pfm");
    let err = write_atomic(&missing, b"x").unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert!(err.to_string().contains("no_such_folder/out.pfm"), "{err}");
    assert!(files_in(dir.path()).is_empty());

    let target_dir = dir.path().join("taken");
    std::fs::create_dir(&target_dir).unwrap();
    assert_format_err(write_atomic(&target_dir, b"x"), &target_dir, "directory");
    assert_eq!(files_in(dir.path()), vec!["taken"]);
    assert!(files_in(&target_dir).is_empty());

    // A socket stands in for device nodes and pipes: it must not be replaced.
    #[cfg(unix)]
    {
        let socket = dir.path().join("sock");
        let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
        assert_format_err(write_atomic(&socket, b"x"), &socket, "not a regular file");
        assert!(!std::fs::metadata(&socket).unwrap().is_file());
        assert_eq!(files_in(dir.path()), vec!["sock", "taken"]);
    }

    let err = write_pfm(&missing, &Image::new(1, 1, 1.0)).unwrap_err();
    assert_names_file(&err.to_string(), &missing);
}

#[test]
fn write_atomic_write_error_removes_temporary() {
    // A read-only folder makes creating the temporary fail; on Linux as root it may succeed,
    // so only check that nothing but the (possibly written) target is left behind.
    let dir = tempdir();
    let sub = dir.path().join("ro");
    std::fs::create_dir(&sub).unwrap();
    let mut perms = std::fs::metadata(&sub).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&sub, perms.clone()).unwrap();
    let target = sub.join("out.bin");
    let result = write_atomic(&target, b"data");
    let left = files_in(&sub);
    #[allow(clippy::permissions_set_readonly_false)]
    perms.set_readonly(false);
    std::fs::set_permissions(&sub, perms).unwrap();
    match result {
        Ok(()) => assert_eq!(left, vec!["out.bin"]),
        Err(err) => {
            assert!(left.is_empty(), "{left:?}");
            assert_names_file(&err.to_string(), &target);
        }
    }
}
