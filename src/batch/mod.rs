//! `stereo-depth batch`: every pair of a folder, a few at a time, resumable and shardable; and
//! `stereo-depth batch-merge`.
//!
//! Pairs are found by [`crate::discover`] on the folder's file list. Each selected pair (all, or
//! one shard's) is handed to [`pair::process`], the pair command's own work, by `jobs` worker
//! threads pulling from a shared index, so at most `jobs` pairs (their images, cost volumes and
//! maps) are in memory at once; the matcher's own threads come from the rayon pool they share.
//!
//! Resuming: a pair whose requested outputs all exist is skipped. Every output is written
//! atomically, so an existing file is complete; and before a pair is (re)done its existing
//! outputs are removed, so a run interrupted in the middle of a pair leaves it incomplete (some
//! output missing) and the next run redoes it rather than mixing old and new files.

pub mod summary;

use std::collections::BTreeSet;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::checks;
use crate::config::{BatchConfig, BatchMergeConfig, PairConfig};
use crate::discover::{self, PairSpec};
use crate::error::UsageError;
use crate::pair;
use crate::report::Stats;
use summary::{Row, Status, Summary, UnpairedRow};

/// Unpaired images listed on stderr before "... and N more".
const UNPAIRED_SHOWN: usize = 10;

/// A pair with its outputs, as selected for this run.
struct Job<'a> {
    index: usize,
    spec: &'a PairSpec,
    /// Relative to OUT_DIR.
    depth: String,
    disparity: Option<String>,
    stats: Option<String>,
    points: Option<String>,
    preview: Option<String>,
    depth_png: Option<String>,
    disparity_png: Option<String>,
}

impl Job<'_> {
    /// Every requested output: the pair is complete when all exist.
    fn outputs(&self) -> impl Iterator<Item = &String> {
        std::iter::once(&self.depth)
            .chain(self.disparity.as_ref())
            .chain(self.disparity_png.as_ref())
            .chain(self.depth_png.as_ref())
            .chain(self.points.as_ref())
            .chain(self.preview.as_ref())
            .chain(self.stats.as_ref())
    }

    fn is_complete(&self, out: &Path) -> bool {
        self.outputs().all(|path| out.join(path).is_file())
    }
}

pub fn run(config: &BatchConfig, out: &mut impl Write) -> Result<ExitCode> {
    let start = Instant::now();
    if !config.input.is_dir() {
        bail!("{}: not a folder (INPUT_DIR)", config.input.display());
    }
    if config.out.exists() && !config.out.is_dir() {
        bail!("{}: not a folder (--out)", config.out.display());
    }
    let files = walk(&config.input, &config.out)?;
    let found = discover::discover(&files, config.pattern.as_ref());
    // Pair after pair: the matcher's strip buffers are kept for the next pair of the same size.
    stereo_disparity::keep_strip_buffers(true);

    if !config.rig.is_complete() {
        let without: Vec<&PairSpec> = found.pairs.iter().filter(|p| p.calib.is_none()).collect();
        if let Some(first) = without.first() {
            return Err(UsageError(format!(
                "{} of {} pairs ({}{}) have no Middlebury calib.txt: give --baseline and the focal \
                 length (--focal and --pixel, --focal-px, or --calib)",
                without.len(),
                found.pairs.len(),
                first.name,
                if without.len() > 1 { ", ..." } else { "" }
            ))
            .into());
        }
    }

    let jobs: Vec<Job> = found
        .pairs
        .iter()
        .enumerate()
        .filter(|(i, _)| config.shard.map_or(true, |s| s.contains(*i)))
        .map(|(index, spec)| Job {
            index,
            spec,
            depth: format!("{}.depth.exr", spec.name),
            disparity: config.disparity.then(|| format!("{}.disparity.pfm", spec.name)),
            stats: config.stats.then(|| format!("{}.stats.json", spec.name)),
            points: config.points.then(|| format!("{}.points.ply", spec.name)),
            preview: config.preview.then(|| format!("{}.preview.png", spec.name)),
            depth_png: config.depth_png.then(|| format!("{}.depth.png", spec.name)),
            disparity_png: config.disparity_png.then(|| format!("{}.disparity.png", spec.name)),
        })
        .collect();
    let summary_stem = match config.shard {
        Some(shard) => format!("summary.{}", shard.tag()),
        None => "summary".to_string(),
    };

    if config.list {
        list(config, &found, &jobs, &summary_stem, out)?;
        return Ok(ExitCode::SUCCESS);
    }

    warn_unpaired(&found.unpaired);
    warn_calib_units(config, &jobs);
    if found.pairs.is_empty() {
        eprintln!("stereo-depth: warning: no stereo pairs found in {}", config.input.display());
    }
    if let Some(threads) = config.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads.into())
            .build_global()
            .context("cannot start the worker threads")?;
    }
    std::fs::create_dir_all(&config.out)
        .with_context(|| format!("cannot create the output folder {}", config.out.display()))?;

    let progress = Progress::new(config.quiet, jobs.len());
    let rows = run_jobs(config, &jobs, &progress);
    progress.finish();

    let wall = start.elapsed();
    let summary = Summary::new(
        config.input.display().to_string(),
        config.out.display().to_string(),
        config.shard,
        found.pairs.len(),
        wall.as_secs_f64(),
        found.unpaired.iter().map(UnpairedRow::from).collect(),
        rows,
    );
    let written = summary.write(&config.out, &summary_stem)?;
    if !config.quiet {
        let processed = summary.ok + summary.failed;
        writeln!(
            out,
            "{} pairs{}: {} ok, {} skipped, {} failed in {:.1} s ({:.2} pairs/s processed)",
            summary.pairs,
            config.shard.map(|s| format!(" (shard {s} of {} pairs)", found.pairs.len())).unwrap_or_default(),
            summary.ok,
            summary.skipped,
            summary.failed,
            wall.as_secs_f64(),
            if wall > Duration::ZERO { processed as f64 / wall.as_secs_f64() } else { 0.0 }
        )?;
        if let Some(raw) = &config.rig.raw {
            let n = raw.cache.computed();
            let times = if n == 1 { "once".to_string() } else { format!("{n} times (once per image size)") };
            writeln!(out, "rectification ({}): maps computed {times}", raw.path.display())?;
        }
    }
    report_written(&summary, &written, out)
}

pub fn merge(config: &BatchMergeConfig, out: &mut impl Write) -> Result<ExitCode> {
    let summary = summary::merge(&config.out)?;
    let written = summary.write(&config.out, "summary")?;
    writeln!(
        out,
        "{} pairs: {} ok, {} skipped, {} failed",
        summary.pairs, summary.ok, summary.skipped, summary.failed
    )?;
    report_written(&summary, &written, out)
}

/// `jobs.len()` rows, in the order of `jobs`.
fn run_jobs(config: &BatchConfig, jobs: &[Job], progress: &Progress) -> Vec<Row> {
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<Option<Row>>> = Mutex::new(vec![None; jobs.len()]);
    let workers = config.jobs.clamp(1, jobs.len().max(1));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = jobs.get(i) else { break };
                let row = run_job(config, job);
                progress.done(&row);
                rows.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(row);
            });
        }
    });
    rows.into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect()
}

fn run_job(config: &BatchConfig, job: &Job) -> Row {
    let start = Instant::now();
    let mut row = Row {
        index: job.index,
        name: job.spec.name.clone(),
        layout: job.spec.layout.name().to_string(),
        status: Status::Ok,
        error: None,
        left: job.spec.left.clone(),
        right: job.spec.right.clone(),
        depth: job.depth.clone(),
        disparity: job.disparity.clone(),
        stats: job.stats.clone(),
        width: None,
        height: None,
        density_percent: None,
        median_depth_m: None,
        load_ms: None,
        match_ms: None,
        triangulate_ms: None,
        write_ms: None,
        total_ms: 0.0,
    };
    if !config.overwrite && job.is_complete(&config.out) {
        row.status = Status::Skipped;
        if let Some(stats) = &job.stats {
            fill_from_stats_file(&mut row, &config.out.join(stats));
        }
    } else {
        match process(config, job) {
            Ok(stats) => fill(&mut row, &stats),
            Err(err) => {
                row.status = Status::Failed;
                row.error = Some(crate::error::one_line(&err));
            }
        }
    }
    row.total_ms = start.elapsed().as_secs_f64() * 1e3;
    row
}

fn process(config: &BatchConfig, job: &Job) -> Result<Stats> {
    let out = &config.out;
    // A pair being (re)done loses its old outputs first: see the module documentation.
    for path in job.outputs() {
        let path = out.join(path);
        match std::fs::remove_file(&path) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
            Err(err) => return Err(err).with_context(|| format!("cannot replace {}", path.display())),
        }
        remove_stale_temporaries(&path);
    }
    let depth = out.join(&job.depth);
    if let Some(folder) = depth.parent() {
        std::fs::create_dir_all(folder)
            .with_context(|| format!("cannot create the output folder {}", folder.display()))?;
    }

    // --calib replaces the pair's own calib.txt (which is then not read).
    let mut rectify = None;
    let found = match (&config.rig.calib, &config.rig.raw, &job.spec.calib) {
        // A raw --calib: the rectifier of this pair's size (maps made once per size).
        (None, Some(raw), _) => {
            let (calib, rectifier) = raw.calib_for(raw.size_for(&config.input.join(&job.spec.left))?)?;
            rectify = Some(rectifier);
            Some(calib)
        }
        (None, None, Some(path)) => Some(stereo_io::read_calib(&config.input.join(path))?),
        _ => None,
    };
    let calib = config.rig.calib(found.as_ref());
    let rig = config.rig.resolve(found.as_ref()).map_err(|err| match (&job.spec.calib, found.is_some()) {
        // The message says "calib.txt"; name the scene's file.
        (Some(path), true) if err.0.starts_with("calib.txt: ") => {
            UsageError(format!("{}: {}", config.input.join(path).display(), &err.0["calib.txt: ".len()..]))
        }
        _ => err,
    })?;
    let settings = &config.matching;
    let max_disparity = settings.max_disparity.or_else(|| {
        let ndisp = calib?.ndisp?;
        Some(i32::try_from(ndisp).unwrap_or(i32::MAX))
    });
    let pair = PairConfig {
        left: config.input.join(&job.spec.left),
        right: config.input.join(&job.spec.right),
        rig: Some(rig),
        min_disparity: settings.min_disparity,
        max_disparity,
        matcher: settings.matcher.clone(),
        output: Some(depth),
        disparity: job.disparity.as_ref().map(|p| out.join(p)),
        stats: job.stats.as_ref().map(|p| out.join(p)),
        points: job.points.as_ref().map(|p| out.join(p)),
        points_step: config.points_step,
        preview: job.preview.as_ref().map(|p| out.join(p)),
        preview_of: config.preview_of,
        depth_png: job.depth_png.as_ref().map(|p| out.join(p)),
        disparity_png: job.disparity_png.as_ref().map(|p| out.join(p)),
        quiet: true,
        expected_size: calib.and_then(|c| Some((c.width?, c.height?))),
        limits: settings.limits,
        extras: settings.extras,
        depth_limits: config.depth_limits,
        align: true,
        rectify,
    };
    pair::process(&pair)
}

/// The unit-mistake warnings of the scenes' own calib.txt files where they give the baseline (no
/// --baseline or --calib), once per file before the work starts. A file that cannot be read is
/// left to fail its pair.
fn warn_calib_units(config: &BatchConfig, jobs: &[Job]) {
    if config.rig.baseline_mm.is_some() || config.rig.calib.is_some() {
        return;
    }
    let files: BTreeSet<&str> = jobs.iter().filter_map(|job| job.spec.calib.as_deref()).collect();
    for file in files {
        let path = config.input.join(file);
        if let Ok(calib) = stereo_io::read_calib(&path) {
            let baseline = calib.baseline_mm.map(|mm| (mm, checks::BaselineSource::Calib(&path)));
            checks::print_warnings(&checks::rig_warnings(baseline, None));
        }
    }
}

/// Removes the temporary files an interrupted run left beside `path` (`.NAME.tmp-PID-N`, see
/// [`stereo_io::atomic_temp_path`]); best effort. Only the pair being redone owns these names.
fn remove_stale_temporaries(path: &Path) {
    let (Some(folder), Some(name)) = (path.parent(), path.file_name().and_then(|n| n.to_str())) else {
        return;
    };
    let prefix = format!(".{name}.tmp-");
    let own = format!("{prefix}{}-", std::process::id());
    let Ok(entries) = std::fs::read_dir(folder) else { return };
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let Some(file) = file_name.to_str() else { continue };
        if file.starts_with(&prefix) && !file.starts_with(&own) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

fn fill(row: &mut Row, stats: &Stats) {
    row.width = Some(stats.width);
    row.height = Some(stats.height);
    row.density_percent = Some(stats.density_percent);
    row.median_depth_m = stats.depth_m.as_ref().map(|d| d.median);
    let t = &stats.timings_ms;
    row.load_ms = Some(t.load);
    row.match_ms = Some(t.match_);
    row.triangulate_ms = Some(t.triangulate);
    row.write_ms = Some(t.write);
}

/// A skipped pair's metrics, from the stats file an earlier run wrote (best effort).
fn fill_from_stats_file(row: &mut Row, path: &Path) {
    let Ok(text) = std::fs::read_to_string(path) else { return };
    let Ok(stats) = serde_json::from_str::<serde_json::Value>(&text) else { return };
    row.width = stats["width"].as_u64().map(|v| v as usize);
    row.height = stats["height"].as_u64().map(|v| v as usize);
    row.density_percent = stats["density_percent"].as_f64();
    row.median_depth_m = stats["depth_m"]["median"].as_f64();
}

/// Every file under `root` as a `/`-separated path relative to it, sorted. Hidden entries
/// (names starting with `.`, e.g. the temporary files of atomic writes) and the output folder
/// are skipped; symbolic links to files are followed, to folders not (no cycles).
fn walk(root: &Path, out: &Path) -> Result<Vec<String>> {
    let out = std::fs::canonicalize(out).ok();
    let mut files = Vec::new();
    let mut stack = vec![(root.to_path_buf(), String::new())];
    while let Some((dir, prefix)) = stack.pop() {
        // OUT_DIR inside INPUT_DIR is skipped (OUT_DIR = INPUT_DIR is fine: outputs are no images).
        if !prefix.is_empty()
            && out.as_deref().is_some_and(|out| std::fs::canonicalize(&dir).is_ok_and(|d| d == out))
        {
            continue;
        }
        let entries =
            std::fs::read_dir(&dir).with_context(|| format!("cannot read the folder {}", dir.display()))?;
        for entry in entries {
            let entry = entry.with_context(|| format!("cannot read the folder {}", dir.display()))?;
            let Some(name) = entry.file_name().to_str().map(str::to_string) else {
                eprintln!(
                    "stereo-depth: warning: skipping {}: the name is not UTF-8",
                    entry.path().display()
                );
                continue;
            };
            if name.starts_with('.') {
                continue;
            }
            let relative = if prefix.is_empty() { name } else { format!("{prefix}/{name}") };
            let file_type =
                entry.file_type().with_context(|| format!("cannot read {}", entry.path().display()))?;
            if file_type.is_dir() {
                stack.push((entry.path(), relative));
            } else if file_type.is_file() || (file_type.is_symlink() && entry.path().is_file()) {
                files.push(relative);
            }
        }
    }
    files.sort();
    Ok(files)
}

fn warn_unpaired(unpaired: &[discover::Unpaired]) {
    for u in unpaired.iter().take(UNPAIRED_SHOWN) {
        eprintln!("stereo-depth: warning: unpaired image {}: {}", u.path, u.reason);
    }
    if unpaired.len() > UNPAIRED_SHOWN {
        eprintln!(
            "stereo-depth: warning: ... and {} more unpaired images (--list shows all)",
            unpaired.len() - UNPAIRED_SHOWN
        );
    }
}

/// `--list`: what a run would do, on stdout; nothing is written.
fn list(
    config: &BatchConfig,
    found: &discover::Discovery,
    jobs: &[Job],
    summary_stem: &str,
    out: &mut impl Write,
) -> Result<()> {
    let mut to_do = 0;
    for job in jobs {
        let skip = !config.overwrite && job.is_complete(&config.out);
        to_do += usize::from(!skip);
        let outputs: Vec<String> = job.outputs().map(|p| config.out.join(p).display().to_string()).collect();
        writeln!(
            out,
            "{}\t{}\t{}{}\t{} + {}\t-> {}",
            if skip { "skip" } else { "process" },
            job.spec.name,
            job.spec.layout.name(),
            if job.spec.calib.is_some() { " (calib.txt)" } else { "" },
            job.spec.left,
            job.spec.right,
            outputs.join(", ")
        )?;
    }
    for u in &found.unpaired {
        writeln!(out, "unpaired\t{}\t{}", u.path, u.reason)?;
    }
    writeln!(
        out,
        "{} pairs{}: {} to process, {} complete (skipped); {} unpaired images; would write {}",
        jobs.len(),
        config.shard.map(|s| format!(" (shard {s} of {} pairs)", found.pairs.len())).unwrap_or_default(),
        to_do,
        jobs.len() - to_do,
        found.unpaired.len(),
        [".json", ".csv"]
            .map(|ext| config.out.join(format!("{summary_stem}{ext}")).display().to_string())
            .join(", ")
    )?;
    out.flush()?;
    Ok(())
}

/// Progress on stderr: a bar on a terminal, a line per pair otherwise, nothing with --quiet
/// (failures are in the summary and counted at the end).
enum Progress {
    Bar(ProgressBar),
    Lines { total: usize, done: AtomicUsize },
    Quiet,
}

impl Progress {
    fn new(quiet: bool, total: usize) -> Progress {
        if quiet {
            Progress::Quiet
        } else if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::stderr());
            let style =
                ProgressStyle::with_template("{bar:30} {pos}/{len} pairs  {elapsed} (eta {eta})  {wide_msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar());
            bar.set_style(style);
            bar.enable_steady_tick(Duration::from_millis(250));
            Progress::Bar(bar)
        } else {
            Progress::Lines { total, done: AtomicUsize::new(0) }
        }
    }

    fn done(&self, row: &Row) {
        let line = match row.status {
            Status::Failed => format!("failed   {}: {}", row.name, row.error.as_deref().unwrap_or("")),
            Status::Skipped => format!("skipped  {} (outputs exist)", row.name),
            Status::Ok => format!(
                "ok       {} ({:.0} ms, {:.1} % valid{})",
                row.name,
                row.total_ms,
                row.density_percent.unwrap_or(0.0),
                row.median_depth_m.map(|m| format!(", median {m:.3} m")).unwrap_or_default()
            ),
        };
        match self {
            Progress::Bar(bar) => {
                if row.status == Status::Failed {
                    bar.println(line);
                }
                bar.set_message(row.name.clone());
                bar.inc(1);
            }
            Progress::Lines { total, done } => {
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                eprintln!("[{n}/{total}] {line}");
            }
            Progress::Quiet => {}
        }
    }

    fn finish(&self) {
        if let Progress::Bar(bar) = self {
            bar.finish_and_clear();
        }
    }
}

/// Prints the summary files written and, when any pair failed, the failure count on stderr;
/// exit status 1 then.
fn report_written(summary: &Summary, written: &[PathBuf], out: &mut impl Write) -> Result<ExitCode> {
    for path in written {
        writeln!(out, "summary: {}", path.display())?;
    }
    out.flush()?;
    if summary.failed > 0 {
        eprintln!(
            "stereo-depth: {} of {} pairs failed (see {})",
            summary.failed,
            summary.pairs,
            written[0].display()
        );
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}
