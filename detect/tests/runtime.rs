//! ONNX Runtime is found in the project virtualenv, loaded, and runs models
//! built by the Python `onnx` package; their interfaces are recognised.

use std::path::{Path, PathBuf};
use std::process::Command;

use detect::Device;
use detect::signature::Signature;
use ort::value::TensorRef;

fn python() -> PathBuf {
    std::env::var_os("POSTFLIGHT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv/bin/python"))
}

/// Two small models: `add_one.onnx` (`y = x + 1` over [1, 3]) and
/// `yolo_shaped.onnx` (images [1, 3, 4, 5] reshaped to output0 [1, 5, 12]).
fn write_models(dir: &Path) {
    let script = r#"
import sys, os, onnx
from onnx import helper, TensorProto
def save(graph, name):
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, os.path.join(sys.argv[1], name))
x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 3])
y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3])
one = helper.make_tensor("one", TensorProto.FLOAT, [1], [1.0])
save(helper.make_graph([helper.make_node("Add", ["x", "one"], ["y"])], "add_one", [x], [y], [one]), "add_one.onnx")
images = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 4, 5])
output = helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 5, 12])
shape = helper.make_tensor("shape", TensorProto.INT64, [3], [1, 5, 12])
save(helper.make_graph([helper.make_node("Reshape", ["images", "shape"], ["output0"])], "yolo_shaped", [images], [output], [shape]), "yolo_shaped.onnx")
"#;
    let out = Command::new(python())
        .args(["-c", script])
        .arg(dir)
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
    write_models(dir.path());
    let mut session = runtime
        .session(&dir.path().join("add_one.onnx"), Device::Cpu)
        .unwrap()
        .session;
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
    drop(outputs);

    // Not a detector: the error names what the model has.
    let err = Signature::of_session(&session).unwrap_err();
    assert!(
        err.contains("x [1, 3]") && err.contains("y [1, 3]"),
        "{err}"
    );
    let yolo = runtime
        .session(&dir.path().join("yolo_shaped.onnx"), Device::Cpu)
        .unwrap()
        .session;
    let signature = Signature::of_session(&yolo).unwrap();
    assert_eq!(signature.classes, Some(1));
    assert_eq!(signature.input_size, Some((4, 5)));
    assert_eq!(
        signature.head,
        detect::signature::Head::Boxes {
            output: "output0".into()
        }
    );

    let Err(err) = runtime.session(&dir.path().join("nope.onnx"), Device::Cpu) else {
        panic!("a missing model opened");
    };
    assert!(err.to_string().contains("--model"), "{err}");

    // The shipped reference detectors have the two YOLO-World interfaces,
    // each with its crack probability map.
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let signature = |name: &str| {
        let opened = runtime.session(&models.join(name), Device::Cpu).unwrap();
        Signature::of_session(&opened.session).unwrap()
    };
    let baked = signature("crack-baked.onnx");
    assert_eq!(baked.vocabulary, detect::signature::Vocabulary::Baked);
    assert_eq!(
        (baked.images.as_str(), baked.classes, baked.input_size),
        ("images", Some(1), None)
    );
    assert_eq!(
        baked.head,
        detect::signature::Head::BoxesAndMap {
            output: "output0".into(),
            map: "mask".into()
        }
    );
    let open = signature("crack-open.onnx");
    assert_eq!(
        open.vocabulary,
        detect::signature::Vocabulary::Embeddings {
            input: "txt_feats".into(),
            dim: 512
        }
    );
}
