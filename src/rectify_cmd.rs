//! Raw pairs from a calibrated rig: the `rectify` command, and the `--calib` hook of the pair
//! and batch commands (a raw calibration is rectified per image size once, then every pair of
//! that size is remapped before matching). The work is in `stereo_rectify`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::args::RectifyArgs;
use anyhow::{anyhow, bail, Context, Result};
use stereo_image::{GrayImage, Image};
use stereo_rectify::{CalibFormat, CalibrationFile, Rectifier, RectifierCache, Sample};

/// A raw calibration given as `--calib`: its rectifiers, one per image size.
#[derive(Debug)]
pub struct RawCalib {
    pub path: PathBuf,
    pub cache: RectifierCache,
}

/// What a `--calib` file turned out to be.
pub enum CalibFlag {
    /// Middlebury calib.txt: an already rectified pair.
    Middlebury(stereo_io::Calib),
    /// A raw calibration: pairs are rectified first.
    Raw(Arc<RawCalib>),
}

/// Reads a `--calib` file of any supported format.
pub fn read_calib_flag(path: &Path, alpha: f64) -> Result<CalibFlag> {
    if !(0.0..=1.0).contains(&alpha) {
        return Err(crate::error::UsageError(format!("invalid --alpha {alpha} (must be in 0..1)")).into());
    }
    match stereo_rectify::read_calibration(path)? {
        CalibrationFile::Middlebury(calib) => Ok(CalibFlag::Middlebury(calib)),
        CalibrationFile::Stereo(calibration) => {
            let cache = RectifierCache::new(Arc::new(*calibration), alpha);
            Ok(CalibFlag::Raw(Arc::new(RawCalib { path: path.to_path_buf(), cache })))
        }
    }
}

impl RawCalib {
    /// How the unit of an OpenCV file's translation was decided (ROS files are in metres), for a
    /// warning when --baseline does not override it.
    pub fn unit_warning(&self) -> Option<String> {
        let calibration = self.cache.calibration();
        (calibration.format != CalibFormat::RosCameraInfo)
            .then(|| format!("{}: {}", self.path.display(), calibration.unit_note))
    }

    /// The rectifier for images of `size` (computed once per size).
    pub fn rectifier(&self, size: (usize, usize)) -> Result<Arc<Rectifier>> {
        self.cache.get(size).map_err(|m| anyhow!("{}: {m}", self.path.display()))
    }

    /// The size of the pair (from `left`'s header; the rectifier checks it against the
    /// calibration's).
    pub fn size_for(&self, left: &Path) -> Result<(usize, usize)> {
        let header = stereo_io::probe_image(left).context("cannot read the left image")?;
        Ok((header.width, header.height))
    }

    /// The rectified rig at `size` as the calibration the rig flags complete themselves from,
    /// and the rectifier.
    pub fn calib_for(&self, size: (usize, usize)) -> Result<(stereo_io::Calib, Arc<Rectifier>)> {
        let rectifier = self.rectifier(size)?;
        let rig = &rectifier.rig;
        let calib = stereo_io::Calib {
            focal_px: rig.focal_px,
            cx: rig.cx,
            cy: rig.cy,
            doffs: Some(rig.doffs),
            baseline_mm: Some(rig.baseline_mm),
            width: Some(size.0),
            height: Some(size.1),
            ndisp: None,
        };
        Ok((calib, rectifier))
    }
}

/// Rectifies a decoded grey pair (both views in parallel).
pub fn rectify_gray(rectifier: &Rectifier, left: &GrayImage, right: &GrayImage) -> (GrayImage, GrayImage) {
    rayon::join(|| rectifier.left.remap(left), || rectifier.right.remap(right))
}

fn rectify_files<P: Sample>(
    rectifier: &Rectifier,
    load: impl Fn(&Path) -> Result<Image<P>> + Sync,
    left: &Path,
    right: &Path,
) -> Result<(Image<P>, Image<P>, f64)> {
    let (l, r) = rayon::join(|| load(left), || load(right));
    let (l, r) = (l.context("cannot read the left image")?, r.context("cannot read the right image")?);
    for (path, image) in [(left, &l), (right, &r)] {
        if image.size() != rectifier.size {
            bail!(
                "{} is {}x{} but the calibration is for {}x{}",
                path.display(),
                image.width(),
                image.height(),
                rectifier.size.0,
                rectifier.size.1
            );
        }
    }
    let t = Instant::now();
    let (l, r) = rayon::join(|| rectifier.left.remap(&l), || rectifier.right.remap(&r));
    Ok((l, r, t.elapsed().as_secs_f64()))
}

pub fn run(args: &RectifyArgs, out: &mut impl Write) -> Result<()> {
    let CalibFlag::Raw(raw) = read_calib_flag(&args.calib, args.alpha)? else {
        bail!(
            "{}: a Middlebury calib.txt describes an already rectified pair: nothing to rectify",
            args.calib.display()
        );
    };
    let header = stereo_io::probe_image(&args.left).context("cannot read the left image")?;
    let size = (header.width, header.height);
    let t = Instant::now();
    let rectifier = raw.rectifier(size)?;
    let maps_s = t.elapsed().as_secs_f64();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create the output folder {}", args.out.display()))?;
    let (im0, im1) = (args.out.join("im0.png"), args.out.join("im1.png"));
    let channels = header.bytes_per_pixel / (header.bits_per_channel / 8).max(1);
    let remap_s = if channels >= 3 {
        let load = |p: &Path| Ok(stereo_io::load_rgb8(p)?);
        let (l, r, s) = rectify_files(&rectifier, load, &args.left, &args.right)?;
        stereo_io::write_png_rgb8(&im0, &l)?;
        stereo_io::write_png_rgb8(&im1, &r)?;
        s
    } else if header.bits_per_channel == 8 {
        let load = |p: &Path| Ok(stereo_io::load_rgb8(p)?.view().map(|[v, _, _]| v));
        let (l, r, s) = rectify_files(&rectifier, load, &args.left, &args.right)?;
        stereo_io::write_png8(&im0, &l)?;
        stereo_io::write_png8(&im1, &r)?;
        s
    } else {
        let load = |p: &Path| Ok(stereo_io::load_gray(p)?);
        let (l, r, s) = rectify_files(&rectifier, load, &args.left, &args.right)?;
        stereo_io::write_png16(&im0, &l)?;
        stereo_io::write_png16(&im1, &r)?;
        s
    };
    let calib_txt = args.out.join("calib.txt");
    stereo_io::write_atomic(&calib_txt, rectifier.middlebury_calib().as_bytes())?;
    let yaml = args.out.join("rectification.yaml");
    stereo_io::write_atomic(&yaml, rectifier.opencv_yaml().as_bytes())?;
    if args.maps {
        for (name, map) in [("left", &rectifier.left), ("right", &rectifier.right)] {
            let (x, y) = map.to_images();
            stereo_io::write_pfm(&args.out.join(format!("{name}_map_x.pfm")), &x)?;
            stereo_io::write_pfm(&args.out.join(format!("{name}_map_y.pfm")), &y)?;
        }
    }
    crate::checks::print_warnings(&raw.unit_warning().into_iter().collect::<Vec<_>>());
    if !args.quiet {
        let cal = raw.cache.calibration();
        let rig = &rectifier.rig;
        writeln!(
            out,
            "{} ({}{}): {}x{}, focal {:.3} px, principal point ({:.3}, {:.3}), baseline {:.3} mm, doffs {:.3}",
            args.calib.display(),
            cal.format.name(),
            if rectifier.computed { format!(", rectified with alpha {}", args.alpha) } else { ", its own R and P".into() },
            size.0,
            size.1,
            rig.focal_px,
            rig.cx,
            rig.cy,
            rig.baseline_mm,
            rig.doffs
        )?;
        writeln!(out, "maps: {:.1} ms; remapping both views: {:.1} ms", maps_s * 1e3, remap_s * 1e3)?;
        for path in [&im0, &im1, &calib_txt, &yaml] {
            writeln!(out, "wrote {}", path.display())?;
        }
    }
    out.flush()?;
    Ok(())
}
