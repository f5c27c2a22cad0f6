//! An OpenSfM / OpenDroneMap `reconstruction.json`.
#![no_main]
libfuzzer_sys::fuzz_target!(|json: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("reconstruction.json");
    std::fs::write(&path, json).unwrap();
    let _ = ingest::reconstruction::Reconstruction::load(&path);
});
