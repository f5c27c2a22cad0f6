//! A batch manifest as given to `postflight batch`: TOML or CSV, one row
//! per flight, and its tasks (a flight's shares among them).
#![no_main]
use fleet::Manifest;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    // The first byte picks the file's kind.
    let Some((&pick, text)) = data.split_first() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let name = if pick & 1 == 0 { "fleet.toml" } else { "fleet.csv" };
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    if let Ok(manifest) = Manifest::load(&path) {
        let tasks = manifest.tasks();
        if let Some(last) = tasks.last() {
            assert!(manifest.task(last.index).is_ok());
        }
    }
});
