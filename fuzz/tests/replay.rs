//! Replays every corpus and regression input through its target without AFL: the
//! harnesses keep building, and every crash ever found stays fixed.

use std::path::Path;

#[test]
fn every_corpus_and_regression_input_returns() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut n = 0;
    for (name, f) in goniospec_fuzz::TARGETS {
        for dir in ["corpus", "regressions"] {
            let d = root.join(dir).join(name);
            let Ok(entries) = std::fs::read_dir(&d) else {
                continue;
            };
            let mut files: Vec<_> = entries.flatten().map(|e| e.path()).collect();
            files.sort();
            for p in files {
                let data = std::fs::read(&p).unwrap();
                f(&data);
                n += 1;
            }
        }
    }
    assert!(
        n >= goniospec_fuzz::TARGETS.len(),
        "no corpus found ({n} inputs)"
    );
    eprintln!("replayed {n} inputs");
}
