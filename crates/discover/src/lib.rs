//! Finding the stereo pairs of a folder, as pure functions over its file list (paths relative to
//! the folder, `/`-separated), so they can be unit-tested and fuzzed without touching the disk.
//!
//! Layouts, all searched at once (a file belongs to at most one pair):
//! - Middlebury: `SCENE/im0.EXT` + `SCENE/im1.EXT`, with `SCENE/calib.txt` when present;
//!   output name `SCENE/im0`.
//! - side folders: `DIR/left/NAME` + `DIR/right/NAME`, KITTI `DIR/image_2/NAME` +
//!   `DIR/image_3/NAME` (and `image_0`/`image_1`); output name `DIR/STEM`.
//! - suffixes: `DIR/NAME_left.EXT` + `DIR/NAME_right.EXT`, `DIR/NAME_L.EXT` + `DIR/NAME_R.EXT`;
//!   output name `DIR/NAME`.
//!
//! or, instead of them, a `--pattern` ([`Pattern`]). Images that end up in no pair are returned
//! with the reason, never dropped.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;

/// Extensions (lower case) of the images the program reads.
pub const IMAGE_EXTENSIONS: [&str; 8] = ["png", "pgm", "ppm", "pnm", "tif", "tiff", "jpg", "jpeg"];

/// Which layout a pair was found in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    Middlebury,
    Kitti,
    Folders,
    Suffix,
    Pattern,
}

impl Layout {
    pub fn name(self) -> &'static str {
        match self {
            Layout::Middlebury => "middlebury",
            Layout::Kitti => "kitti",
            Layout::Folders => "left-right-folders",
            Layout::Suffix => "suffix",
            Layout::Pattern => "pattern",
        }
    }
}

/// One pair: paths relative to the input folder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairSpec {
    /// Output base name, relative to the output folder, without extension (`DIR/STEM`); unique.
    pub name: String,
    pub left: String,
    pub right: String,
    /// The Middlebury `calib.txt` beside the pair, if any.
    pub calib: Option<String>,
    pub layout: Layout,
}

/// An image that is in no pair, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unpaired {
    pub path: String,
    pub reason: String,
}

#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Discovery {
    /// Sorted by name.
    pub pairs: Vec<PairSpec>,
    /// Sorted by path.
    pub unpaired: Vec<Unpaired>,
}

pub fn is_image(path: &str) -> bool {
    let (_, name) = split_dir(path);
    name.rsplit_once('.').is_some_and(|(stem, ext)| {
        !stem.is_empty() && IMAGE_EXTENSIONS.contains(&ext.to_ascii_lowercase().as_str())
    })
}

/// `("a/b", "c.png")` for `a/b/c.png`, `("", "c.png")` for `c.png`.
fn split_dir(path: &str) -> (&str, &str) {
    path.rsplit_once('/').unwrap_or(("", path))
}

/// `(stem, ".ext")`; the extension is empty when there is none.
fn split_ext(name: &str) -> (&str, &str) {
    match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name, ""),
    }
}

fn join(dir: &str, name: &str) -> String {
    if dir.is_empty() {
        name.to_string()
    } else {
        format!("{dir}/{name}")
    }
}

/// Side-folder names: (left, right, layout).
const SIDE_FOLDERS: [(&str, &str, Layout); 3] = [
    ("left", "right", Layout::Folders),
    ("image_2", "image_3", Layout::Kitti),
    ("image_0", "image_1", Layout::Kitti),
];
/// File-name suffixes: (left, right).
const SUFFIXES: [(&str, &str); 2] = [("_left", "_right"), ("_L", "_R")];

/// The pairs in `files` (relative `/`-separated paths, in any order; non-images are ignored
/// except `calib.txt`), by the known layouts or, when given, only by `pattern`.
pub fn discover(files: &[String], pattern: Option<&Pattern>) -> Discovery {
    let all: BTreeSet<&str> = files.iter().map(String::as_str).collect();
    let mut candidates = Vec::new();
    let mut hints: BTreeMap<&str, String> = BTreeMap::new();
    match pattern {
        Some(pattern) => pattern.candidates(&all, &mut candidates, &mut hints),
        None => known_layouts(&all, &mut candidates, &mut hints),
    }

    // A file belongs to at most one pair, and names are unique: first candidate wins (the
    // candidates come in a fixed order, so the result is deterministic).
    let mut claimed: BTreeMap<&str, String> = BTreeMap::new();
    let mut names: BTreeSet<String> = BTreeSet::new();
    let mut pairs = Vec::new();
    let mut conflicts: BTreeMap<String, String> = BTreeMap::new();
    for pair in candidates {
        if claimed.contains_key(pair.left.as_str()) || claimed.contains_key(pair.right.as_str()) {
            continue;
        }
        if names.contains(&pair.name) {
            for path in [&pair.left, &pair.right] {
                conflicts.insert(
                    path.clone(),
                    format!("its pair's output name {} is already taken by another pair", pair.name),
                );
            }
            continue;
        }
        let left = *all.get(pair.left.as_str()).expect("candidates are files of the list");
        let right = *all.get(pair.right.as_str()).expect("candidates are files of the list");
        claimed.insert(left, pair.name.clone());
        claimed.insert(right, pair.name.clone());
        names.insert(pair.name.clone());
        pairs.push(pair);
    }
    pairs.sort_by(|a, b| a.name.cmp(&b.name));

    let mut unpaired = Vec::new();
    for &path in &all {
        let is_candidate = is_image(path) || hints.contains_key(path);
        if !is_candidate || claimed.contains_key(path) {
            continue;
        }
        let reason =
            conflicts.remove(path).or_else(|| hints.get(path).cloned()).unwrap_or_else(|| match pattern {
                Some(_) => "does not match --pattern".to_string(),
                None => "matches no known layout (see --pattern)".to_string(),
            });
        unpaired.push(Unpaired { path: path.to_string(), reason });
    }
    Discovery { pairs, unpaired }
}

fn known_layouts<'a>(
    all: &BTreeSet<&'a str>,
    candidates: &mut Vec<PairSpec>,
    hints: &mut BTreeMap<&'a str, String>,
) {
    let images: Vec<&str> = all.iter().copied().filter(|p| is_image(p)).collect();
    // The right image of a left one: same extension first, then any image extension.
    let find = |dir: &str, stem: &str, ext: &str| -> Option<String> {
        let same = join(dir, &format!("{stem}{ext}"));
        if all.contains(same.as_str()) {
            return Some(same);
        }
        IMAGE_EXTENSIONS
            .iter()
            .flat_map(|e| [e.to_string(), e.to_ascii_uppercase()])
            .map(|e| join(dir, &format!("{stem}.{e}")))
            .find(|p| all.contains(p.as_str()))
    };

    // Middlebury.
    for &path in &images {
        let (dir, name) = split_dir(path);
        let (stem, ext) = split_ext(name);
        if stem == "im0" {
            match find(dir, "im1", ext) {
                Some(right) => {
                    let calib = join(dir, "calib.txt");
                    candidates.push(PairSpec {
                        name: join(dir, "im0"),
                        left: path.to_string(),
                        right,
                        calib: all.contains(calib.as_str()).then_some(calib),
                        layout: Layout::Middlebury,
                    });
                }
                None => {
                    hints.insert(path, format!("no right image {}", join(dir, &format!("im1{ext}"))));
                }
            }
        } else if stem == "im1" && find(dir, "im0", ext).is_none() {
            hints.insert(path, format!("no left image {}", join(dir, &format!("im0{ext}"))));
        }
    }

    // Side folders (left/right, KITTI).
    for &path in &images {
        let (dir, name) = split_dir(path);
        let (parent, folder) = split_dir(dir);
        if dir.is_empty() {
            continue;
        }
        for (left, right, layout) in SIDE_FOLDERS {
            let (partner_folder, is_left) = if folder == left {
                (right, true)
            } else if folder == right {
                (left, false)
            } else {
                continue;
            };
            let partner = join(&join(parent, partner_folder), name);
            if !all.contains(partner.as_str()) {
                let side = if is_left { "right" } else { "left" };
                hints.insert(path, format!("no {side} image {partner}"));
            } else if is_left {
                let (stem, _) = split_ext(name);
                candidates.push(PairSpec {
                    name: join(parent, stem),
                    left: path.to_string(),
                    right: partner,
                    calib: None,
                    layout,
                });
            }
        }
    }

    // Suffixes.
    for &path in &images {
        let (dir, name) = split_dir(path);
        let (stem, ext) = split_ext(name);
        for (left, right) in SUFFIXES {
            let (base, partner_suffix, is_left) = if let Some(base) = stem.strip_suffix(left) {
                (base, right, true)
            } else if let Some(base) = stem.strip_suffix(right) {
                (base, left, false)
            } else {
                continue;
            };
            if base.is_empty() {
                continue;
            }
            match find(dir, &format!("{base}{partner_suffix}"), ext) {
                Some(partner) if is_left => candidates.push(PairSpec {
                    name: join(dir, base),
                    left: path.to_string(),
                    right: partner,
                    calib: None,
                    layout: Layout::Suffix,
                }),
                Some(_) => {}
                None => {
                    let side = if is_left { "right" } else { "left" };
                    let expected = join(dir, &format!("{base}{partner_suffix}{ext}"));
                    hints.insert(path, format!("no {side} image {expected}"));
                }
            }
        }
    }
}

/// `--pattern LEFT:RIGHT`: two templates with one `{name}` each. A template without `/` is
/// matched against file names in every folder (output `DIR/{name}`); with `/`, against paths
/// from the input folder (output `{name}`, which may then contain `/`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pattern {
    left: Template,
    right: Template,
}

#[derive(Clone, Debug, PartialEq, Eq)]
struct Template {
    prefix: String,
    suffix: String,
}

impl Template {
    fn parse(text: &str) -> Result<Template, String> {
        let Some((prefix, suffix)) = text.split_once("{name}") else {
            return Err(format!("{text:?} has no {{name}}"));
        };
        if suffix.contains("{name}") {
            return Err(format!("{text:?} has more than one {{name}}"));
        }
        if prefix.contains(['{', '}']) || suffix.contains(['{', '}']) {
            return Err(format!("{text:?}: only {{name}} may be in braces"));
        }
        if prefix.starts_with('/') || suffix.ends_with('/') {
            return Err(format!("{text:?} must name files relative to INPUT_DIR"));
        }
        Ok(Template { prefix: prefix.to_string(), suffix: suffix.to_string() })
    }

    fn has_slash(&self) -> bool {
        self.prefix.contains('/') || self.suffix.contains('/')
    }

    fn capture<'a>(&self, text: &'a str) -> Option<&'a str> {
        let name = text.strip_prefix(self.prefix.as_str())?.strip_suffix(self.suffix.as_str())?;
        (!name.is_empty()).then_some(name)
    }

    fn fill(&self, name: &str) -> String {
        format!("{}{name}{}", self.prefix, self.suffix)
    }
}

impl Pattern {
    pub fn parse(text: &str) -> Result<Pattern, String> {
        let mut sides = text.split(':');
        let (Some(left), Some(right), None) = (sides.next(), sides.next(), sides.next()) else {
            return Err("want LEFT:RIGHT, two templates separated by one ':'".into());
        };
        let (left, right) = (Template::parse(left)?, Template::parse(right)?);
        if left == right {
            return Err("the left and right templates are the same".into());
        }
        if left.has_slash() != right.has_slash() {
            return Err("either both templates or neither may contain '/'".into());
        }
        Ok(Pattern { left, right })
    }

    /// `(name, left path, right path)` when `path` matches the left template.
    fn match_left(&self, path: &str) -> Option<(String, String)> {
        if self.left.has_slash() {
            let name = self.left.capture(path)?;
            Some((name.to_string(), self.right.fill(name)))
        } else {
            let (dir, file) = split_dir(path);
            let name = self.left.capture(file)?;
            Some((join(dir, name), join(dir, &self.right.fill(name))))
        }
    }

    /// The left path for `path` when it matches the right template.
    fn match_right(&self, path: &str) -> Option<String> {
        if self.right.has_slash() {
            Some(self.left.fill(self.right.capture(path)?))
        } else {
            let (dir, file) = split_dir(path);
            Some(join(dir, &self.left.fill(self.right.capture(file)?)))
        }
    }

    fn candidates<'a>(
        &self,
        all: &BTreeSet<&'a str>,
        candidates: &mut Vec<PairSpec>,
        hints: &mut BTreeMap<&'a str, String>,
    ) {
        for &path in all {
            if let Some((name, right)) = self.match_left(path) {
                if all.contains(right.as_str()) {
                    candidates.push(PairSpec {
                        name,
                        left: path.to_string(),
                        right,
                        calib: None,
                        layout: Layout::Pattern,
                    });
                } else {
                    hints.insert(path, format!("no right image {right} (--pattern)"));
                }
            } else if let Some(left) = self.match_right(path) {
                if !all.contains(left.as_str()) {
                    hints.insert(path, format!("no left image {left} (--pattern)"));
                }
            }
        }
    }
}

/// `--shard K/N`: the pairs whose index in the sorted list is K modulo N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (k, n) = text.split_once('/').ok_or("want K/N, e.g. 0/4")?;
        let index: usize = k.trim().parse().map_err(|_| format!("K {k:?} is not a whole number"))?;
        let count: usize = n.trim().parse().map_err(|_| format!("N {n:?} is not a whole number"))?;
        if count == 0 {
            return Err("N must be at least 1".into());
        }
        if index >= count {
            return Err(format!("K must be in 0..{count} (0-based), got {index}"));
        }
        Ok(Shard { index, count })
    }

    pub fn contains(&self, pair_index: usize) -> bool {
        pair_index % self.count == self.index
    }

    /// `shard-K-of-N`, in the summary file names.
    pub fn tag(&self) -> String {
        format!("shard-{}-of-{}", self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    fn names(d: &Discovery) -> Vec<(&str, &str, &str)> {
        d.pairs.iter().map(|p| (p.name.as_str(), p.left.as_str(), p.right.as_str())).collect()
    }

    fn unpaired(d: &Discovery) -> Vec<&str> {
        d.unpaired.iter().map(|u| u.path.as_str()).collect()
    }

    #[test]
    fn left_right_folders_at_any_depth() {
        let d = discover(
            &files(&[
                "left/b.png",
                "right/b.png",
                "left/a.png",
                "right/a.png",
                "x/left/c.png",
                "x/right/c.png",
                "left/lonely.png",
                "right/other.png",
            ]),
            None,
        );
        assert_eq!(
            names(&d),
            [
                ("a", "left/a.png", "right/a.png"),
                ("b", "left/b.png", "right/b.png"),
                ("x/c", "x/left/c.png", "x/right/c.png")
            ]
        );
        assert!(d.pairs.iter().all(|p| p.layout == Layout::Folders));
        assert_eq!(unpaired(&d), ["left/lonely.png", "right/other.png"]);
        assert_eq!(d.unpaired[0].reason, "no right image right/lonely.png");
        assert_eq!(d.unpaired[1].reason, "no left image left/other.png");
    }

    #[test]
    fn suffixes() {
        let d = discover(
            &files(&[
                "s/a_left.png",
                "s/a_right.png",
                "b_L.jpg",
                "b_R.jpg",
                "c_left.png",
                "d_R.png",
                "e_left.png",
                "e_right.PNG",
            ]),
            None,
        );
        assert_eq!(
            names(&d),
            [
                ("b", "b_L.jpg", "b_R.jpg"),
                ("e", "e_left.png", "e_right.PNG"),
                ("s/a", "s/a_left.png", "s/a_right.png")
            ]
        );
        assert_eq!(unpaired(&d), ["c_left.png", "d_R.png"]);
        assert_eq!(d.unpaired[1].reason, "no left image d_L.png");
    }

    #[test]
    fn middlebury_with_and_without_calib() {
        let d = discover(
            &files(&[
                "Art/im0.png",
                "Art/im1.png",
                "Art/calib.txt",
                "Art/disp0.pfm",
                "Bike/im0.png",
                "Bike/im1.png",
                "Cone/im0.png",
            ]),
            None,
        );
        assert_eq!(
            names(&d),
            [("Art/im0", "Art/im0.png", "Art/im1.png"), ("Bike/im0", "Bike/im0.png", "Bike/im1.png")]
        );
        assert_eq!(d.pairs[0].calib.as_deref(), Some("Art/calib.txt"));
        assert_eq!(d.pairs[1].calib, None);
        assert_eq!(d.pairs[0].layout, Layout::Middlebury);
        assert_eq!(unpaired(&d), ["Cone/im0.png"]);
    }

    #[test]
    fn kitti() {
        let d = discover(
            &files(&[
                "training/image_2/000000_10.png",
                "training/image_3/000000_10.png",
                "training/image_2/000001_10.png",
                "training/image_3/000001_10.png",
                "training/disp_noc_0/000000_10.png",
            ]),
            None,
        );
        assert_eq!(
            names(&d),
            [
                ("training/000000_10", "training/image_2/000000_10.png", "training/image_3/000000_10.png"),
                ("training/000001_10", "training/image_2/000001_10.png", "training/image_3/000001_10.png")
            ]
        );
        assert!(d.pairs.iter().all(|p| p.layout == Layout::Kitti));
        assert_eq!(unpaired(&d), ["training/disp_noc_0/000000_10.png"]);
        assert!(d.unpaired[0].reason.contains("no known layout"));
    }

    #[test]
    fn non_images_and_order_of_input_do_not_matter() {
        let mut list =
            files(&["a_left.png", "a_right.png", "notes.txt", "left/z.png", "right/z.png", "README"]);
        let d = discover(&list, None);
        list.reverse();
        assert_eq!(discover(&list, None), d);
        assert_eq!(names(&d), [("a", "a_left.png", "a_right.png"), ("z", "left/z.png", "right/z.png")]);
        assert!(d.unpaired.is_empty());
    }

    #[test]
    fn name_collisions_are_reported() {
        let d = discover(&files(&["left/a.png", "right/a.png", "a_left.png", "a_right.png"]), None);
        assert_eq!(names(&d), [("a", "left/a.png", "right/a.png")]);
        assert_eq!(unpaired(&d), ["a_left.png", "a_right.png"]);
        assert!(d.unpaired[0].reason.contains("already taken"));
    }

    #[test]
    fn patterns() {
        let p = Pattern::parse("{name}_a.png:{name}_b.png").unwrap();
        let d = discover(
            &files(&[
                "x_a.png",
                "x_b.png",
                "sub/y_a.png",
                "sub/y_b.png",
                "z_a.png",
                "left/q.png",
                "right/q.png",
            ]),
            Some(&p),
        );
        assert_eq!(names(&d), [("sub/y", "sub/y_a.png", "sub/y_b.png"), ("x", "x_a.png", "x_b.png")]);
        assert!(d.pairs.iter().all(|p| p.layout == Layout::Pattern));
        assert_eq!(unpaired(&d), ["left/q.png", "right/q.png", "z_a.png"]);
        assert_eq!(d.unpaired[2].reason, "no right image z_b.png (--pattern)");

        let p = Pattern::parse("cam0/{name}.png:cam1/{name}.png").unwrap();
        let d = discover(&files(&["cam0/t/1.png", "cam1/t/1.png", "cam0/2.png"]), Some(&p));
        assert_eq!(names(&d), [("t/1", "cam0/t/1.png", "cam1/t/1.png")]);

        for bad in [
            "{name}.png",
            "a:b",
            "{name}.png:{name}.png",
            "{name}{name}:{name}_b",
            "a/{name}:{name}_b",
            "x:y:z",
            "{nam}:{name}",
        ] {
            assert!(Pattern::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn shards_partition_the_indices() {
        for n in [1, 2, 3, 7] {
            let shards: Vec<Shard> = (0..n).map(|k| Shard::parse(&format!("{k}/{n}")).unwrap()).collect();
            for i in 0..50 {
                assert_eq!(shards.iter().filter(|s| s.contains(i)).count(), 1);
            }
        }
        assert_eq!(Shard::parse("3/7").unwrap().tag(), "shard-3-of-7");
        for bad in ["", "1", "2/2", "0/0", "-1/3", "a/3", "1/b"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
