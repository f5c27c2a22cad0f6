//! Finding and starting ONNX Runtime.
//!
//! postflight loads ONNX Runtime as a shared library at run time (`ort`'s
//! `load-dynamic`), because prebuilt-binary downloads are impossible on
//! air-gapped sites. The library comes from the `onnxruntime` Python wheel;
//! [`locate`] looks for it in a fixed order and says exactly where it looked.

use postflight_core::setting::inputs::{self, ONNXRUNTIME};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use ort::ep::{self, ExecutionProvider};
use ort::session::builder::SessionBuilder;

use crate::error::DetectError;
use crate::settings::keys;

/// Where the ONNX Runtime library was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Library {
    pub path: PathBuf,
    /// `--onnxruntime`, `ORT_DYLIB_PATH`, `project virtualenv` or `python3`.
    pub found_by: &'static str,
}

/// Find the ONNX Runtime shared library, in order: `explicit` (the
/// `--onnxruntime` flag), `ORT_DYLIB_PATH`, the project virtualenv (`.venv`
/// of the checkout postflight was built from, or above the executable or the
/// working directory), then the `onnxruntime` package of `python3` on PATH.
pub fn locate(explicit: Option<&Path>) -> Result<Library, DetectError> {
    if let Some(path) = explicit {
        return if path.is_file() {
            Ok(Library {
                path: path.to_owned(),
                found_by: "--onnxruntime",
            })
        } else {
            Err(DetectError::Runtime(format!(
                "{ONNXRUNTIME} {} is not a file; give the path of libonnxruntime.so",
                path.display()
            )))
        };
    }
    let mut tried = Vec::new();
    if let Some(path) = std::env::var_os("ORT_DYLIB_PATH").map(PathBuf::from) {
        if path.is_file() {
            return Ok(Library {
                path,
                found_by: "ORT_DYLIB_PATH",
            });
        }
        tried.push(format!("ORT_DYLIB_PATH={} (no such file)", path.display()));
    } else {
        tried.push("ORT_DYLIB_PATH (unset)".into());
    }
    // The checkout postflight was built from, then wherever it runs from.
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf);
    let starts = [
        checkout,
        std::env::current_exe().ok(),
        std::env::current_dir().ok(),
    ];
    for start in starts.iter().flatten() {
        for dir in start.ancestors() {
            let venv = dir.join(".venv");
            if venv.is_dir() {
                if let Some(path) = in_venv(&venv) {
                    return Ok(Library {
                        path,
                        found_by: "project virtualenv",
                    });
                }
                tried.push(format!("{} (no onnxruntime package)", venv.display()));
            }
        }
    }
    match python_package() {
        Some(path) => {
            return Ok(Library {
                path,
                found_by: "python3",
            });
        }
        None => tried.push("python3 on PATH (no onnxruntime package)".into()),
    }
    Err(DetectError::Runtime(format!(
        "ONNX Runtime not found (no {ONNXRUNTIME}; {}); run scripts/setup, or `pip install onnxruntime==1.31.1`, or pass {ONNXRUNTIME} /path/to/libonnxruntime.so",
        tried.join(", ")
    )))
}

/// `libonnxruntime.so*` in a virtualenv's `onnxruntime/capi`.
fn in_venv(venv: &Path) -> Option<PathBuf> {
    let lib = venv.join("lib");
    let mut pythons: Vec<PathBuf> = std::fs::read_dir(&lib)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("python"))
        })
        .collect();
    pythons.sort();
    pythons
        .iter()
        .find_map(|py| in_capi(&py.join("site-packages/onnxruntime/capi")))
}

/// The library in an `onnxruntime/capi` directory: the versioned file if
/// there is one (`libonnxruntime.so.1.31.1`), else `libonnxruntime.so`.
fn in_capi(capi: &Path) -> Option<PathBuf> {
    let mut libs: Vec<PathBuf> = std::fs::read_dir(capi)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.starts_with("libonnxruntime.so")
                    || n == "libonnxruntime.dylib"
                    || n == "onnxruntime.dll"
            })
        })
        .collect();
    // The longest name is the most specific version.
    libs.sort_by_key(|p| std::cmp::Reverse(p.as_os_str().len()));
    libs.into_iter().next()
}

/// `OrtGetApiBase()->GetVersionString()` of the library at `path` (already
/// loaded by `ort`, so this only looks the symbol up); the build information
/// `ort::info()` gives names no release in the PyPI wheels.
fn library_version(path: &Path) -> Option<String> {
    // SAFETY: the library is ONNX Runtime, which `ort` loaded from the same
    // path and checked; `OrtGetApiBase` has this signature in every release,
    // returns a static table, and `GetVersionString` a static C string.
    unsafe {
        let lib = libloading::Library::new(path).ok()?;
        let get: libloading::Symbol<unsafe extern "C" fn() -> *const ort::sys::OrtApiBase> =
            lib.get(b"OrtGetApiBase").ok()?;
        let base = get();
        if base.is_null() {
            return None;
        }
        let text = ((*base).GetVersionString)();
        (!text.is_null()).then(|| {
            std::ffi::CStr::from_ptr(text)
                .to_string_lossy()
                .into_owned()
        })
    }
}

fn python_package() -> Option<PathBuf> {
    let out = Command::new("python3")
        .args([
            "-c",
            "import onnxruntime, os; print(os.path.dirname(onnxruntime.__file__))",
        ])
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let dir = PathBuf::from(String::from_utf8(out.stdout).ok()?.trim());
    in_capi(&dir.join("capi"))
}

/// A started ONNX Runtime, ready to create sessions.
pub struct Runtime {
    pub library: Library,
    pub environment: ort::environment::Environment,
}

/// ONNX Runtime allows one environment per process: the first start keeps it.
static STARTED: Mutex<Option<&'static Runtime>> = Mutex::new(None);

impl Runtime {
    /// Load the library and create the environment, once per process; later
    /// calls with the same library get the same runtime.
    pub fn start(library: Library) -> Result<&'static Self, DetectError> {
        let mut started = STARTED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(runtime) = *started {
            return if runtime.library.path == library.path {
                Ok(runtime)
            } else {
                Err(DetectError::Runtime(format!(
                    "ONNX Runtime is already loaded from {} in this process; it cannot also load {}",
                    runtime.library.path.display(),
                    library.path.display()
                )))
            };
        }
        let builder = ort::init_from(&library.path).map_err(|e| {
            DetectError::Runtime(format!(
                "cannot load ONNX Runtime from {} (found by {}): {e}; reinstall it with scripts/setup",
                library.path.display(),
                library.found_by
            ))
        })?;
        let environment = builder
            .with_name("postflight")
            .build()
            .map_err(|e| DetectError::Runtime(format!("cannot start ONNX Runtime: {e}")))?;
        let runtime = Box::leak(Box::new(Self {
            library,
            environment,
        }));
        *started = Some(runtime);
        Ok(runtime)
    }

    /// The library's version (`1.31.1`), as the library itself reports it.
    pub fn version(&self) -> String {
        library_version(&self.library.path).unwrap_or_else(|| "unknown".into())
    }

    /// Open a model on `device`, falling back to the CPU (with a warning in
    /// the returned [`Session`]) when the library or machine cannot run it there.
    pub fn session(&self, model: &Path, device: Device) -> Result<Session, DetectError> {
        let bad = |e: ort::Error| DetectError::Model {
            path: model.to_owned(),
            why: e.to_string(),
        };
        if let Err(e) = postflight_core::user_file::check(model) {
            return Err(DetectError::Model {
                path: model.to_owned(),
                why: format!("{e}; check the path given to {}", inputs::MODEL),
            });
        }
        let builder = ort::session::Session::builder(&self.environment).map_err(bad)?;
        let cpu = |mut builder: SessionBuilder, warning: Option<String>| {
            Ok(Session {
                session: builder.commit_from_file(model).map_err(bad)?,
                device: Device::Cpu,
                warning,
            })
        };
        let (name, available, provider, needs) = match device {
            Device::Cpu => return cpu(builder, None),
            Device::Cuda => (
                "CUDA",
                ep::CUDA::is_available(),
                ep::CUDA::default().build().error_on_failure(),
                "the onnxruntime-gpu wheel, and the CUDA and cuDNN libraries it was built for on LD_LIBRARY_PATH",
            ),
            Device::TensorRt => (
                "TensorRT",
                ep::TensorRT::is_available(),
                ep::TensorRT::default().build().error_on_failure(),
                "the onnxruntime-gpu wheel, and CUDA, cuDNN and TensorRT's libnvinfer on LD_LIBRARY_PATH",
            ),
        };
        let fallback = |why: String| {
            Some(format!(
                "{} {}: {why}; running on the CPU ({name} inference needs {needs})",
                keys::device,
                device.as_str()
            ))
        };
        if !available.unwrap_or(false) {
            let why = format!(
                "the ONNX Runtime library {} has no {name} execution provider",
                self.library.path.display()
            );
            return cpu(builder, fallback(why));
        }
        match builder.with_execution_providers([provider]) {
            Ok(mut builder) => match builder.commit_from_file(model) {
                Ok(session) => Ok(Session {
                    session,
                    device,
                    warning: None,
                }),
                // The provider registered but could not load this model
                // (missing cuDNN, unsupported operators): a fresh CPU session.
                Err(e) => {
                    let why = format!(
                        "{name} could not run the model: {}",
                        ort_reason(&e.to_string())
                    );
                    let builder = ort::session::Session::builder(&self.environment).map_err(bad)?;
                    cpu(builder, fallback(why))
                }
            },
            Err(e) => {
                let why = format!("{name} could not start: {}", ort_reason(&e.to_string()));
                cpu(e.recover(), fallback(why))
            }
        }
    }
}

/// ONNX Runtime's own words for an error, on one line: without the source
/// location and status code it puts first (`/onnxruntime_src/...cc:2043
/// ... [ONNXRuntimeError] : 1 : FAIL : `) and the line break it ends with.
fn ort_reason(text: &str) -> String {
    let reason = match text.split_once("[ONNXRuntimeError]") {
        Some((_, rest)) => rest.splitn(4, " : ").last().unwrap_or(rest),
        None => text,
    };
    reason.split_whitespace().collect::<Vec<_>>().join(" ")
}

pub use postflight_core::detection::Device;

/// An opened model and the device it actually runs on.
pub struct Session {
    pub session: ort::session::Session,
    pub device: Device,
    /// Why it runs on the CPU although another device was asked for.
    pub warning: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn onnx_runtime_errors_are_cut_to_their_reason_on_one_line() {
        // As the onnxruntime-gpu 1.31.1 wheel said on a machine without TensorRT.
        let said = "/onnxruntime_src/onnxruntime/core/session/provider_bridge_ort.cc:2043 onnxruntime::Provider& onnxruntime::ProviderLibrary::Get() [ONNXRuntimeError] : 1 : FAIL : Failed to load library /tmp/gpu/libonnxruntime_providers_tensorrt.so with error: libnvinfer.so.10: cannot open shared object file: No such file or directory\n";
        assert_eq!(
            ort_reason(said),
            "Failed to load library /tmp/gpu/libonnxruntime_providers_tensorrt.so with error: libnvinfer.so.10: cannot open shared object file: No such file or directory"
        );
        assert_eq!(ort_reason("no such\nprovider "), "no such provider");
    }
}
