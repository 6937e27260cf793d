//! The batch summary: one row per pair, as `summary.json` and `summary.csv` (or
//! `summary.shard-K-of-N.*` for a shard), and the merge of the shard summaries.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use crate::discover::{Shard, Unpaired};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Processed now.
    Ok,
    /// All requested outputs were already there (and --overwrite was not given).
    Skipped,
    Failed,
}

impl Status {
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Skipped => "skipped",
            Status::Failed => "failed",
        }
    }
}

/// One pair. Paths are relative: inputs to INPUT_DIR, outputs to OUT_DIR. Metrics are `null`
/// when unknown (a failed pair, or a skipped one without a stats file).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// Position in the sorted list of all pairs (before sharding).
    pub index: usize,
    pub name: String,
    pub layout: String,
    pub status: Status,
    pub error: Option<String>,
    pub left: String,
    pub right: String,
    pub depth: String,
    pub disparity: Option<String>,
    pub stats: Option<String>,
    pub width: Option<usize>,
    pub height: Option<usize>,
    pub density_percent: Option<f64>,
    pub median_depth_m: Option<f64>,
    pub load_ms: Option<f64>,
    pub match_ms: Option<f64>,
    pub triangulate_ms: Option<f64>,
    pub write_ms: Option<f64>,
    /// Wall time spent on the pair in this run, including the completeness check.
    pub total_ms: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct UnpairedRow {
    pub path: String,
    pub reason: String,
}

impl From<&Unpaired> for UnpairedRow {
    fn from(u: &Unpaired) -> Self {
        UnpairedRow { path: u.path.clone(), reason: u.reason.clone() }
    }
}

/// The JSON document.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    pub input: String,
    pub out: String,
    /// `K/N` for a shard's summary, `null` for a whole run or a merge.
    pub shard: Option<String>,
    /// Pairs found in INPUT_DIR, before sharding.
    pub total_pairs: usize,
    /// Rows in this summary.
    pub pairs: usize,
    pub ok: usize,
    pub skipped: usize,
    pub failed: usize,
    /// Seconds from the start of the run to the summary (for a merge: the sum over the shards).
    pub wall_s: f64,
    pub unpaired: Vec<UnpairedRow>,
    pub rows: Vec<Row>,
}

impl Summary {
    pub fn new(
        input: String,
        out: String,
        shard: Option<Shard>,
        total_pairs: usize,
        wall_s: f64,
        unpaired: Vec<UnpairedRow>,
        mut rows: Vec<Row>,
    ) -> Summary {
        rows.sort_by_key(|r| r.index);
        let count = |status| rows.iter().filter(|r| r.status == status).count();
        Summary {
            input,
            out,
            shard: shard.map(|s| s.to_string()),
            total_pairs,
            pairs: rows.len(),
            ok: count(Status::Ok),
            skipped: count(Status::Skipped),
            failed: count(Status::Failed),
            wall_s,
            unpaired,
            rows,
        }
    }

    /// Writes `STEM.json` and `STEM.csv` in `dir` (atomically); returns their paths.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<[PathBuf; 2]> {
        let json_path = dir.join(format!("{stem}.json"));
        let csv_path = dir.join(format!("{stem}.csv"));
        let mut json = serde_json::to_vec_pretty(self).context("cannot serialise the summary")?;
        json.push(b'\n');
        stereo_io::write_atomic(&json_path, &json).context("cannot write the summary")?;
        stereo_io::write_atomic(&csv_path, self.csv().as_bytes()).context("cannot write the summary")?;
        Ok([json_path, csv_path])
    }

    pub fn csv(&self) -> String {
        let mut out = String::from(
            "index,name,status,error,left,right,depth,disparity,stats,width,height,density_percent,\
             median_depth_m,load_ms,match_ms,triangulate_ms,write_ms,total_ms\n",
        );
        let num = |v: Option<f64>| v.map(|v| format!("{v:.3}")).unwrap_or_default();
        let int = |v: Option<usize>| v.map(|v| v.to_string()).unwrap_or_default();
        for r in &self.rows {
            let fields = [
                r.index.to_string(),
                csv_field(&r.name),
                r.status.name().to_string(),
                csv_field(r.error.as_deref().unwrap_or("")),
                csv_field(&r.left),
                csv_field(&r.right),
                csv_field(&r.depth),
                csv_field(r.disparity.as_deref().unwrap_or("")),
                csv_field(r.stats.as_deref().unwrap_or("")),
                int(r.width),
                int(r.height),
                num(r.density_percent),
                r.median_depth_m.map(|v| format!("{v:.6}")).unwrap_or_default(),
                num(r.load_ms),
                num(r.match_ms),
                num(r.triangulate_ms),
                num(r.write_ms),
                num(Some(r.total_ms)),
            ];
            let _ = writeln!(out, "{}", fields.join(","));
        }
        out
    }
}

/// RFC 4180: quoted when it holds a comma, quote or line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// `summary.shard-K-of-N.json` -> `(K, N)`.
fn shard_of(file_name: &str) -> Option<(usize, usize)> {
    let rest = file_name.strip_prefix("summary.shard-")?.strip_suffix(".json")?;
    let (k, n) = rest.split_once("-of-")?;
    Some((k.parse().ok()?, n.parse().ok()?))
}

/// Joins the shard summaries in `out` into one [`Summary`]. Every shard 0..N of one N must be
/// there, the rows must not overlap, and together they must hold every pair.
pub fn merge(out: &Path) -> Result<Summary> {
    let entries =
        std::fs::read_dir(out).with_context(|| format!("cannot read the folder {}", out.display()))?;
    let mut shards: BTreeMap<usize, BTreeMap<usize, PathBuf>> = BTreeMap::new();
    for entry in entries {
        let entry = entry.with_context(|| format!("cannot read the folder {}", out.display()))?;
        if let Some((k, n)) = entry.file_name().to_str().and_then(shard_of) {
            shards.entry(n).or_default().insert(k, entry.path());
        }
    }
    let (count, files) = match shards.len() {
        0 => bail!("{}: no shard summaries (summary.shard-K-of-N.json) to merge", out.display()),
        1 => shards.into_iter().next().expect("one entry"),
        _ => bail!(
            "{}: shard summaries of different shard counts ({}); remove the stale ones",
            out.display(),
            shards.keys().map(|n| format!("of {n}")).collect::<Vec<_>>().join(", ")
        ),
    };
    let missing: Vec<String> = (0..count).filter(|k| !files.contains_key(k)).map(|k| k.to_string()).collect();
    if !missing.is_empty() {
        bail!(
            "{}: missing the summaries of shard(s) {} of {count}; run them before merging",
            out.display(),
            missing.join(", ")
        );
    }
    let mut rows: BTreeMap<usize, Row> = BTreeMap::new();
    let mut first: Option<Summary> = None;
    let mut wall_s = 0.0;
    for path in files.values() {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let summary: Summary = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a batch summary", path.display()))?;
        if let Some(first) = &first {
            if first.total_pairs != summary.total_pairs {
                bail!(
                    "{}: found {} pairs but shard {} found {}; were the shards run on the same input?",
                    path.display(),
                    summary.total_pairs,
                    first.shard.as_deref().unwrap_or("?"),
                    first.total_pairs
                );
            }
        }
        wall_s += summary.wall_s;
        for row in &summary.rows {
            if let Some(other) = rows.insert(row.index, row.clone()) {
                bail!("pair {} ({}) is in two shard summaries", row.index, other.name);
            }
        }
        first.get_or_insert(summary);
    }
    let first = first.expect("at least one shard");
    if rows.len() != first.total_pairs {
        bail!(
            "the shard summaries hold {} of the {} pairs; were the shards run on the same input?",
            rows.len(),
            first.total_pairs
        );
    }
    Ok(Summary::new(
        first.input,
        first.out,
        None,
        first.total_pairs,
        wall_s,
        first.unpaired,
        rows.into_values().collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_fields_are_quoted_when_needed() {
        assert_eq!(csv_field("a/b.png"), "a/b.png");
        assert_eq!(csv_field("x, \"y\""), "\"x, \"\"y\"\"\"");
    }

    #[test]
    fn shard_file_names() {
        assert_eq!(shard_of("summary.shard-3-of-7.json"), Some((3, 7)));
        assert_eq!(shard_of("summary.shard-3-of-7.csv"), None);
        assert_eq!(shard_of("summary.json"), None);
    }
}
