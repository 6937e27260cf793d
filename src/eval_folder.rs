//! `stereo-depth eval-folder DIR`: runs the matcher on every scene of a folder with ground truth
//! (a `scenes.tsv` folder like `../shared/data`, or Middlebury `SCENE/im0.png im1.png
//! disp0GT.pfm calib.txt` folders) and prints a per-scene table with the average.

use std::io::Write;

use anyhow::{Context, Result};
use stereo_disparity::DisparityRange;

use crate::args::EvalFolderArgs;
use crate::config::{MatchSettings, UsageError};
use crate::pair::run_matcher;

pub fn run(args: &EvalFolderArgs, out: &mut impl Write) -> Result<()> {
    let settings = MatchSettings::from_args(&args.matching)?;
    let results = stereo_eval::try_evaluate_folder(&args.dir, |left, right, ndisp| {
        let max = match settings.max_disparity {
            Some(max) => max,
            None => settings.min_disparity + ndisp as i32,
        };
        let range =
            DisparityRange::new(settings.min_disparity, max).map_err(|e| UsageError(e.to_string()))?;
        let mut matcher = settings.matcher.clone();
        matcher.set_range(range);
        run_matcher(&matcher, left, right, &args.dir, settings.extras.min_confidence).map(|m| m.disparity)
    })
    .with_context(|| format!("cannot evaluate {}", args.dir.display()))?;
    if args.json {
        let average = stereo_eval::average(&results);
        let json = serde_json::json!({ "scenes": results, "average": average });
        writeln!(out, "{}", serde_json::to_string_pretty(&json)?)?;
    } else {
        write!(out, "{}", stereo_eval::format_table(&results))?;
    }
    Ok(())
}
