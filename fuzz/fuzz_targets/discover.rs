//! Pair discovery and the --pattern / --shard parsers on arbitrary input. The first line is a
//! --pattern (used when it parses), the second a --shard, the rest the folder's file list.
//! Checked: no panic; every file is in at most one pair; pair names are unique; every pair's files
//! are in the list; unpaired images are never paired.
#![no_main]

use std::collections::BTreeSet;

use libfuzzer_sys::fuzz_target;
use stereo_discover::{discover, Pattern, Shard};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let mut lines = text.split('\n');
    let pattern = lines.next().and_then(|p| Pattern::parse(p).ok());
    if let Some(Ok(shard)) = lines.next().map(Shard::parse) {
        let _ = shard.tag();
        let _ = shard.contains(usize::MAX);
    }
    let files: Vec<String> = lines.filter(|l| !l.is_empty()).map(str::to_string).collect();
    let all: BTreeSet<&str> = files.iter().map(String::as_str).collect();
    for pattern in [None, pattern.as_ref()] {
        let found = discover(&files, pattern);
        let mut used = BTreeSet::new();
        let mut names = BTreeSet::new();
        for pair in &found.pairs {
            assert!(names.insert(pair.name.as_str()), "duplicate name {}", pair.name);
            for file in [&pair.left, &pair.right] {
                assert!(all.contains(file.as_str()), "{file} not in the list");
                assert!(used.insert(file.as_str()), "{file} in two pairs");
            }
            assert_ne!(pair.left, pair.right);
        }
        for u in &found.unpaired {
            assert!(!used.contains(u.path.as_str()), "{} both paired and unpaired", u.path);
        }
        if pattern.is_none() {
            break;
        }
    }
});
