//! Prints the rectification of a calibration file at an image size and writes its maps.
//!
//! `cargo run -p stereo-rectify --example rectify_dump -- stereo.yaml WIDTH HEIGHT [ALPHA [OUT_DIR]]`
//! prints `R1 R2 P1 P2` (OpenCV YAML) and the rectified rig; with OUT_DIR, writes the maps as
//! PFM (`left_x.pfm`, `left_y.pfm`, `right_x.pfm`, `right_y.pfm`).

use std::path::PathBuf;

use stereo_rectify::{read_calibration, CalibrationFile, Rectifier};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: rectify_dump CALIB WIDTH HEIGHT [ALPHA [OUT_DIR]]".into());
    }
    let path = PathBuf::from(&args[0]);
    let size = (args[1].parse()?, args[2].parse()?);
    let alpha = args.get(3).map(|a| a.parse()).transpose()?.unwrap_or(0.0);
    let CalibrationFile::Stereo(calibration) = read_calibration(&path)? else {
        return Err("a Middlebury calib.txt: already rectified".into());
    };
    let t = std::time::Instant::now();
    let rectifier =
        Rectifier::new(&calibration, size, alpha).map_err(|m| format!("{}: {m}", path.display()))?;
    eprintln!("maps in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    print!("{}", rectifier.opencv_yaml());
    eprintln!("{:?}", rectifier.rig);
    if let Some(dir) = args.get(4) {
        let dir = PathBuf::from(dir);
        for (name, map) in [("left", &rectifier.left), ("right", &rectifier.right)] {
            let (x, y) = map.to_images();
            stereo_io::write_pfm(&dir.join(format!("{name}_x.pfm")), &x)?;
            stereo_io::write_pfm(&dir.join(format!("{name}_y.pfm")), &y)?;
        }
    }
    Ok(())
}
