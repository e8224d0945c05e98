//! ONNX Runtime, loaded from a shared library at run time, and a thin model
//! runner over it.
//!
//! The library is found in this order (first hit wins):
//! 1. an explicit path (the CLI's `--ort-lib`),
//! 2. the `ORT_DYLIB_PATH` environment variable,
//! 3. `.deps/onnxruntime/onnxruntime/capi/libonnxruntime.so*` (where
//!    `make deps` puts the PyPI wheel's library) below any of the first four
//!    ancestors of the running executable (covers `target/release/omcl` and
//!    `target/debug/deps/<test>`) and below the crate root this binary was
//!    built from,
//! 4. `libonnxruntime.so` on the system's library path.
//!
//! An explicit path or environment variable that names a missing file is an
//! error, not a silent fall-through: the user asked for that file.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use ort::session::{Session, SessionInputValue};
use ort::value::{Tensor, TensorElementType, ValueType};

use super::EncodeError;

/// Where `make deps` installs the `onnxruntime` wheel, relative to a root.
pub const DEPS_CAPI_DIR: &str = ".deps/onnxruntime/onnxruntime/capi";

/// Environment variable that names the library (ort's own convention).
pub const ENV_VAR: &str = "ORT_DYLIB_PATH";

/// Lists the places searched for the runtime library, in order. `explicit`
/// is the `--ort-lib` value, `env` the value of `ORT_DYLIB_PATH`, `exe` the
/// running executable and `crate_root` the source tree the binary was built
/// from. Directories are expanded to the library files they hold.
pub fn library_candidates(
    explicit: Option<&Path>,
    env: Option<&Path>,
    exe: Option<&Path>,
    crate_root: &Path,
) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut roots: Vec<PathBuf> = Vec::new();
    if let Some(dir) = exe.and_then(Path::parent) {
        roots.extend(dir.ancestors().take(4).map(Path::to_path_buf));
    }
    roots.push(crate_root.to_path_buf());
    for p in [explicit, env].into_iter().flatten() {
        out.push(p.to_path_buf());
    }
    for root in roots {
        out.extend(libraries_in(&root.join(DEPS_CAPI_DIR)));
    }
    out
}

/// The `libonnxruntime.so*` files in `dir` (not the providers' libraries),
/// longest (most specific version) name first.
fn libraries_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut libs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libonnxruntime.so") || n == "libonnxruntime.dylib")
        })
        .collect();
    libs.sort_by_key(|p| std::cmp::Reverse(p.as_os_str().len()));
    libs
}

/// Resolves the runtime library by the documented search order.
pub fn find_library(explicit: Option<&Path>) -> Result<PathBuf, EncodeError> {
    let env = std::env::var_os(ENV_VAR)
        .filter(|v| !v.is_empty())
        .map(PathBuf::from);
    let exe = std::env::current_exe().ok();
    resolve_library(
        explicit,
        env.as_deref(),
        exe.as_deref(),
        Path::new(env!("CARGO_MANIFEST_DIR")),
        &SYSTEM_DIRS.map(Path::new),
    )
}

/// The usual system directories searched last for `libonnxruntime.so`.
const SYSTEM_DIRS: [&str; 4] = [
    "/usr/local/lib",
    "/usr/lib",
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
];

/// [`find_library`] with every input given, so the search is testable;
/// `system_dirs` are the directories searched last, for a bare
/// `libonnxruntime.so`.
pub fn resolve_library(
    explicit: Option<&Path>,
    env: Option<&Path>,
    exe: Option<&Path>,
    crate_root: &Path,
    system_dirs: &[&Path],
) -> Result<PathBuf, EncodeError> {
    for (given, what) in [(explicit, "--ort-lib"), (env, ENV_VAR)] {
        if let Some(p) = given {
            return if p.is_file() {
                Ok(p.to_path_buf())
            } else {
                Err(EncodeError::RuntimeNotFound {
                    tried: format!("{} (from {what}: no such file)", p.display()),
                })
            };
        }
    }
    let cands = library_candidates(None, None, exe, crate_root);
    if let Some(p) = cands.into_iter().find(|p| p.is_file()) {
        return Ok(p);
    }
    // Last resort: the system library path. We cannot test for the file, so
    // hand dlopen the bare name and report NotFound if that fails too.
    let mut tried: Vec<String> = Vec::new();
    if let Some(dir) = exe.and_then(Path::parent) {
        tried.extend(
            dir.ancestors()
                .take(4)
                .map(|r| r.join(DEPS_CAPI_DIR).display().to_string()),
        );
    }
    tried.push(crate_root.join(DEPS_CAPI_DIR).display().to_string());
    tried.push("libonnxruntime.so on the system library path".into());
    if system_dirs
        .iter()
        .any(|d| d.join("libonnxruntime.so").is_file())
    {
        return Ok(PathBuf::from("libonnxruntime.so"));
    }
    Err(EncodeError::RuntimeNotFound {
        tried: tried.join(", "),
    })
}

/// The process-wide ONNX Runtime: the loaded library and its environment.
/// ONNX Runtime allows one environment per process, so this is a singleton;
/// the first successful [`Runtime::init`] fixes the library.
pub struct Runtime {
    library: PathBuf,
    env: ort::environment::Environment,
}

static RUNTIME: OnceLock<Runtime> = OnceLock::new();
static INIT: Mutex<()> = Mutex::new(());

impl Runtime {
    /// Loads the runtime library (see the module docs for the search order)
    /// unless it is loaded already, and returns the process-wide runtime.
    pub fn init(explicit: Option<&Path>) -> Result<&'static Runtime, EncodeError> {
        if let Some(rt) = RUNTIME.get() {
            return Ok(rt);
        }
        // Two threads racing here would both try to build the one allowed
        // environment; serialise them.
        let _guard = INIT.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(rt) = RUNTIME.get() {
            return Ok(rt);
        }
        let library = find_library(explicit)?;
        let builder = ort::init_from(&library).map_err(|e| EncodeError::RuntimeLoad {
            path: library.clone(),
            reason: e.to_string(),
        })?;
        let env = builder
            .with_name("omcl")
            .with_telemetry(false)
            .build()
            .map_err(|e| EncodeError::Runtime(e.to_string()))?;
        Ok(RUNTIME.get_or_init(|| Runtime { library, env }))
    }

    /// The shared library this process loaded.
    pub fn library(&self) -> &Path {
        &self.library
    }
}

/// Element type of a model input or output, as far as encoders care.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ElemKind {
    F32,
    I64,
    I32,
    /// Anything else, by ONNX Runtime's name for it.
    Other(String),
}

/// Name, element type and dimensions (`None` = symbolic or dynamic) of one
/// model input or output.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorSpec {
    pub name: String,
    pub elem: ElemKind,
    pub dims: Vec<Option<usize>>,
}

impl TensorSpec {
    fn from_outlet(name: &str, dtype: &ValueType) -> TensorSpec {
        let (elem, dims) = match dtype {
            ValueType::Tensor { ty, shape, .. } => {
                let elem = match ty {
                    TensorElementType::Float32 => ElemKind::F32,
                    TensorElementType::Int64 => ElemKind::I64,
                    TensorElementType::Int32 => ElemKind::I32,
                    other => ElemKind::Other(other.to_string()),
                };
                let dims = shape
                    .iter()
                    .map(|&d| usize::try_from(d).ok().filter(|&d| d > 0))
                    .collect();
                (elem, dims)
            }
            other => (ElemKind::Other(other.to_string()), Vec::new()),
        };
        TensorSpec {
            name: name.to_string(),
            elem,
            dims,
        }
    }

    /// Whether a tensor of `shape` fits these dimensions.
    pub fn accepts(&self, shape: &[usize]) -> bool {
        shape.len() == self.dims.len()
            && self
                .dims
                .iter()
                .zip(shape)
                .all(|(d, &s)| d.is_none_or(|d| d == s))
    }

    /// The dimensions as text, `?` for dynamic ones: `[1, 3, ?, ?]`.
    pub fn dims_text(&self) -> String {
        let parts: Vec<String> = self
            .dims
            .iter()
            .map(|d| d.map_or("?".to_string(), |d| d.to_string()))
            .collect();
        format!("[{}]", parts.join(", "))
    }
}

/// Data for one model input, row-major.
#[derive(Debug, Clone)]
pub enum InputData {
    F32(Vec<f32>),
    I64(Vec<i64>),
    I32(Vec<i32>),
}

impl InputData {
    fn len(&self) -> usize {
        match self {
            InputData::F32(v) => v.len(),
            InputData::I64(v) => v.len(),
            InputData::I32(v) => v.len(),
        }
    }
}

/// One `f32` output of a model run: its shape and row-major values.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputTensor {
    pub name: String,
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

/// A loaded ONNX model with its input and output signature.
pub struct OnnxModel {
    path: PathBuf,
    session: Session,
    inputs: Vec<TensorSpec>,
    outputs: Vec<TensorSpec>,
}

impl OnnxModel {
    /// Loads `path` into a session on the CPU. `intra_threads` = 0 leaves
    /// ONNX Runtime's default (one thread per physical core).
    pub fn load(
        runtime: &Runtime,
        path: &Path,
        intra_threads: usize,
    ) -> Result<OnnxModel, EncodeError> {
        // A missing file is an I/O error, not "not ONNX".
        std::fs::metadata(path).map_err(|err| EncodeError::Io {
            path: path.to_path_buf(),
            err,
        })?;
        let rt_err = |e: String| EncodeError::Runtime(format!("{}: {e}", path.display()));
        let mut builder = Session::builder(&runtime.env).map_err(|e| rt_err(e.to_string()))?;
        if intra_threads > 0 {
            builder = builder
                .with_intra_threads(intra_threads)
                .map_err(|e| rt_err(e.to_string()))?;
        }
        let session = builder
            .commit_from_file(path)
            .map_err(|e| EncodeError::NotOnnx {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        let inputs = session
            .inputs()
            .iter()
            .map(|o| TensorSpec::from_outlet(o.name(), o.dtype()))
            .collect();
        let outputs = session
            .outputs()
            .iter()
            .map(|o| TensorSpec::from_outlet(o.name(), o.dtype()))
            .collect();
        Ok(OnnxModel {
            path: path.to_path_buf(),
            session,
            inputs,
            outputs,
        })
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The model's inputs in graph order.
    pub fn inputs(&self) -> &[TensorSpec] {
        &self.inputs
    }

    /// The model's outputs in graph order.
    pub fn outputs(&self) -> &[TensorSpec] {
        &self.outputs
    }

    /// The input named `name`, or the first input when `name` is `None`.
    pub fn input(&self, name: Option<&str>) -> Result<&TensorSpec, EncodeError> {
        find_spec(&self.path, &self.inputs, name, "input")
    }

    /// The output named `name`, or the first output when `name` is `None`.
    pub fn output(&self, name: Option<&str>) -> Result<&TensorSpec, EncodeError> {
        find_spec(&self.path, &self.outputs, name, "output")
    }

    /// Runs the model on named inputs and returns the named `f32` outputs,
    /// in the order asked. Shapes and element types are checked against the
    /// model's signature first, so a mismatch gets an error naming the
    /// input and both shapes rather than ONNX Runtime's internal message.
    pub fn run(
        &mut self,
        inputs: Vec<(&str, &[usize], InputData)>,
        outputs: &[&str],
    ) -> Result<Vec<OutputTensor>, EncodeError> {
        let mut values: Vec<(Cow<'_, str>, SessionInputValue<'_>)> = Vec::new();
        for (name, shape, data) in inputs {
            let spec = find_spec(&self.path, &self.inputs, Some(name), "input")?;
            let n: usize = shape.iter().product();
            if n != data.len() {
                return Err(EncodeError::Input(format!(
                    "{}: input `{name}` of shape {shape:?} needs {n} values, got {}",
                    self.path.display(),
                    data.len()
                )));
            }
            if !spec.accepts(shape) {
                return Err(EncodeError::Shape {
                    path: self.path.clone(),
                    what: format!("input `{name}`"),
                    got: shape.to_vec(),
                    expected: spec.dims_text(),
                });
            }
            let shape_i64: Vec<i64> = shape.iter().map(|&d| d as i64).collect();
            let mk = |e: ort::Error| EncodeError::Run {
                path: self.path.clone(),
                reason: e.to_string(),
            };
            let value: SessionInputValue<'_> = match (data, &spec.elem) {
                (InputData::F32(v), ElemKind::F32) => Tensor::from_array((shape_i64, v.clone()))
                    .map_err(mk)?
                    .into(),
                (InputData::I64(v), ElemKind::I64) => Tensor::from_array((shape_i64, v.clone()))
                    .map_err(mk)?
                    .into(),
                (InputData::I32(v), ElemKind::I32) => Tensor::from_array((shape_i64, v.clone()))
                    .map_err(mk)?
                    .into(),
                (_, want) => {
                    return Err(EncodeError::Contract {
                        path: self.path.clone(),
                        reason: format!(
                            "input `{name}` has element type {want:?}, which this encoder does not feed"
                        ),
                    });
                }
            };
            values.push((Cow::Owned(name.to_string()), value));
        }
        for o in outputs {
            find_spec(&self.path, &self.outputs, Some(o), "output")?;
        }
        let path = self.path.clone();
        let run_err = |e: ort::Error| EncodeError::Run {
            path: path.clone(),
            reason: e.to_string(),
        };
        let result = self.session.run(values).map_err(run_err)?;
        let mut out = Vec::with_capacity(outputs.len());
        for o in outputs {
            let value = result.get(*o).ok_or_else(|| EncodeError::Contract {
                path: path.clone(),
                reason: format!("model returned no output `{o}`"),
            })?;
            let (shape, data) =
                value
                    .try_extract_tensor::<f32>()
                    .map_err(|e| EncodeError::Contract {
                        path: path.clone(),
                        reason: format!("output `{o}` is not a float32 tensor: {e}"),
                    })?;
            out.push(OutputTensor {
                name: o.to_string(),
                shape: shape.iter().map(|&d| d.max(0) as usize).collect(),
                data: data.to_vec(),
            });
        }
        Ok(out)
    }
}

fn find_spec<'a>(
    path: &Path,
    specs: &'a [TensorSpec],
    name: Option<&str>,
    what: &str,
) -> Result<&'a TensorSpec, EncodeError> {
    let found = match name {
        Some(n) => specs.iter().find(|s| s.name == n),
        None => specs.first(),
    };
    found.ok_or_else(|| {
        let names: Vec<&str> = specs.iter().map(|s| s.name.as_str()).collect();
        EncodeError::Contract {
            path: path.to_path_buf(),
            reason: format!(
                "model has no {what} named `{}`; its {what}s are {names:?}",
                name.unwrap_or("<first>")
            ),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn explicit_path_wins_and_a_missing_one_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let lib = dir.path().join("libonnxruntime.so.1.2.3");
        std::fs::write(&lib, b"x").unwrap();
        let other = dir.path().join("other.so");
        std::fs::write(&other, b"x").unwrap();
        let got = resolve_library(Some(&lib), Some(&other), None, dir.path(), &[]).unwrap();
        assert_eq!(got, lib);
        let got = resolve_library(None, Some(&other), None, dir.path(), &[]).unwrap();
        assert_eq!(got, other);
        let missing = dir.path().join("nope.so");
        let e = resolve_library(Some(&missing), None, None, dir.path(), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("nope.so") && e.contains("make deps"), "{e}");
    }

    #[test]
    fn deps_directory_is_found_above_the_executable() {
        let dir = tempfile::tempdir().unwrap();
        let capi = dir.path().join(DEPS_CAPI_DIR);
        std::fs::create_dir_all(&capi).unwrap();
        std::fs::write(capi.join("libonnxruntime.so.1.31.1"), b"x").unwrap();
        std::fs::write(capi.join("libonnxruntime_providers_shared.so"), b"x").unwrap();
        let exe = dir.path().join("target/debug/deps/test-abc");
        let elsewhere = tempfile::tempdir().unwrap();
        let got = resolve_library(None, None, Some(&exe), elsewhere.path(), &[]).unwrap();
        assert_eq!(got, capi.join("libonnxruntime.so.1.31.1"));
    }

    #[test]
    fn nothing_found_says_how_to_install() {
        let dir = tempfile::tempdir().unwrap();
        let (exe, system) = (dir.path().join("bin/omcl"), dir.path().join("lib"));
        std::fs::create_dir_all(&system).unwrap();
        let e = resolve_library(None, None, Some(&exe), dir.path(), &[&system])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("make deps") && e.contains("ORT_DYLIB_PATH"),
            "{e}"
        );
        // A library in a system directory is the last resort, by bare name.
        std::fs::write(system.join("libonnxruntime.so"), b"x").unwrap();
        let got = resolve_library(None, None, Some(&exe), dir.path(), &[&system]).unwrap();
        assert_eq!(got, PathBuf::from("libonnxruntime.so"));
    }

    #[test]
    fn spec_accepts_dynamic_and_rejects_wrong_dims() {
        let s = TensorSpec {
            name: "x".into(),
            elem: ElemKind::F32,
            dims: vec![Some(1), Some(3), None, None],
        };
        assert!(s.accepts(&[1, 3, 10, 20]));
        assert!(!s.accepts(&[1, 4, 10, 20]));
        assert!(!s.accepts(&[3, 10, 20]));
        assert_eq!(s.dims_text(), "[1, 3, ?, ?]");
    }
}
