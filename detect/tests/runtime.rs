//! ONNX Runtime is found in the project virtualenv, loaded, and runs a model
//! built by the Python `onnx` package.

use std::path::{Path, PathBuf};
use std::process::Command;

use ort::value::TensorRef;

fn python() -> PathBuf {
    std::env::var_os("POSTFLIGHT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv/bin/python"))
}

/// `y = x + 1` over a [1, 3] float tensor.
fn add_one_model(path: &Path) {
    let script = r#"
import sys, onnx
from onnx import helper, TensorProto
x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 3])
y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3])
one = helper.make_tensor("one", TensorProto.FLOAT, [1], [1.0])
graph = helper.make_graph([helper.make_node("Add", ["x", "one"], ["y"])], "add_one", [x], [y], [one])
model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
model.ir_version = 8
onnx.checker.check_model(model)
onnx.save(model, sys.argv[1])
"#;
    let out = Command::new(python())
        .args(["-c", script])
        .arg(path)
        .output()
        .expect("run the project Python (scripts/setup makes it)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn finds_loads_and_runs_onnx_runtime() {
    let dir = tempfile::tempdir().unwrap();
    // SAFETY: this test binary has a single test; nothing else reads the environment concurrently.
    unsafe { std::env::set_var("XDG_CACHE_HOME", dir.path().join("cache")) };
    unsafe { std::env::remove_var("ORT_DYLIB_PATH") };

    let missing = detect::locate(Some(Path::new("/nonexistent/libonnxruntime.so"))).unwrap_err();
    assert!(missing.to_string().contains("--onnxruntime"), "{missing}");

    let library = detect::locate(None).unwrap();
    assert_eq!(library.found_by, "project virtualenv");
    assert!(
        library
            .path
            .to_string_lossy()
            .contains("onnxruntime/capi/libonnxruntime.so")
    );

    let runtime = detect::Runtime::start(library).unwrap();
    let model = dir.path().join("add_one.onnx");
    add_one_model(&model);
    let mut session = runtime.session(&model).unwrap();
    assert_eq!(session.inputs()[0].name(), "x");
    let input = ndarray::arr2(&[[1.0f32, 2.0, -3.5]]);
    let outputs = session
        .run(ort::inputs![TensorRef::from_array_view(&input).unwrap()])
        .unwrap();
    let y = outputs["y"].try_extract_array::<f32>().unwrap();
    assert_eq!(
        y.iter().copied().collect::<Vec<f32>>(),
        vec![2.0, 3.0, -2.5]
    );

    let err = runtime.session(&dir.path().join("nope.onnx")).unwrap_err();
    assert!(err.to_string().contains("--model"), "{err}");
}
