//! Replays every input that fuzzing found to crash, hang or exhaust memory
//! (fuzz/regressions/TARGET/*, kept by tools/fuzz), and the malformed-input
//! corpus, through the same entry points the fuzzing targets call
//! (`trazo::fuzz`): each must now return normally.

use std::path::Path;

fn replay(target: &str, read: fn(&[u8]), dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut count = 0;
    for e in entries {
        let path = e.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        let result = std::panic::catch_unwind(|| read(&bytes));
        assert!(result.is_ok(), "{target}: {} still fails", path.display());
        count += 1;
    }
    count
}

#[test]
fn inputs_found_by_fuzzing_no_longer_fail() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut replayed = 0;
    for (target, read) in trazo::fuzz::TARGETS {
        replayed += replay(target, read, &root.join("fuzz/regressions").join(target));
    }
    assert!(replayed > 0, "no regression inputs found under fuzz/regressions");
}

#[test]
fn the_malformed_corpus_goes_through_the_fuzzing_entry_points() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed");
    let mut replayed = 0;
    for (target, read) in trazo::fuzz::TARGETS {
        replayed += replay(target, read, &root.join(target));
    }
    assert!(replayed >= 80, "only {replayed} corpus files");
}
