//! `stereo-depth eval-folder DIR`: runs the matcher on every scene of a folder with ground truth
//! (a `scenes.tsv` folder like `../shared/data`, or Middlebury `SCENE/im0.png im1.png
//! disp0GT.pfm calib.txt` folders) and prints a per-scene table with the average.

use std::io::Write;

use anyhow::{Context, Result};
use stereo_pipeline::{DisparityRange, PipelineParams, Plan};

use crate::config::EvalFolderConfig;
use crate::error::UsageError;

pub fn run(config: &EvalFolderConfig, out: &mut impl Write) -> Result<()> {
    let settings = &config.settings;
    let results = stereo_eval::try_evaluate_folder(&config.dir, |left, right, ndisp| {
        let max = match settings.max_disparity {
            Some(max) => max,
            None => settings.min_disparity + ndisp as i32,
        };
        let range =
            DisparityRange::new(settings.min_disparity, max).map_err(|e| UsageError(e.to_string()))?;
        let mut matcher = settings.matcher.clone();
        matcher.set_range(range);
        let mut params = PipelineParams::new(matcher);
        // Scored as the matcher sees the pair: the benchmark pairs are rectified.
        params.align = false;
        params.min_confidence = settings.extras.min_confidence;
        let plan = Plan::new(&params, left.size(), right.size()).map_err(|e| UsageError(e.to_string()))?;
        plan.run_gray(left, right.clone())
            .map(|result| result.disparity)
            .map_err(|e| anyhow::Error::new(e).context(format!("{}: matching failed", config.dir.display())))
    })
    .with_context(|| format!("cannot evaluate {}", config.dir.display()))?;
    if config.json {
        let average = stereo_eval::average(&results);
        let json = serde_json::json!({ "scenes": results, "average": average });
        writeln!(out, "{}", serde_json::to_string_pretty(&json)?)?;
    } else {
        write!(out, "{}", stereo_eval::format_table(&results))?;
    }
    Ok(())
}
