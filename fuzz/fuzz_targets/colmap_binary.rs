//! A COLMAP binary model: `cameras.bin`, `images.bin` and `points3D.bin`,
//! the input split in three at its first two NUL bytes.
#![no_main]
libfuzzer_sys::fuzz_target!(|input: &[u8]| {
    let mut parts = input.splitn(3, |b| *b == 0);
    let dir = tempfile::tempdir().unwrap();
    for name in ["cameras.bin", "images.bin", "points3D.bin"] {
        std::fs::write(dir.path().join(name), parts.next().unwrap_or_default()).unwrap();
    }
    let _ = ingest::reconstruction::Reconstruction::load(dir.path());
});
