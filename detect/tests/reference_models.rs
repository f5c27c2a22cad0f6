//! The shipped reference detectors are exactly what their build script makes.

use std::path::{Path, PathBuf};
use std::process::Command;

fn python() -> PathBuf {
    std::env::var_os("POSTFLIGHT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv/bin/python"))
}

#[test]
fn shipped_reference_models_are_what_the_script_builds() {
    let dir = tempfile::tempdir().unwrap();
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let out = Command::new(python())
        .arg(models.join("build_reference.py"))
        .arg(dir.path())
        .output()
        .expect("run the project Python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for file in [
        "crack-baked.onnx",
        "crack-open.onnx",
        "crack-semantic.onnx",
        "area-reference.onnx",
        "prompts.json",
    ] {
        let built = std::fs::read(dir.path().join(file)).unwrap();
        let shipped = std::fs::read(models.join(file)).unwrap();
        assert!(
            built == shipped,
            "{file} is stale: rerun detect/models/build_reference.py"
        );
    }
}
