//! `motile._motile`: the compiled half of the Python package `motile`. Thin bindings over the
//! Rust crates: run directories read through `motile-experiments`' readers, runs through its
//! run loop (the CLI's), analysis through `motile-analysis` and the Bingham closure of
//! `motile-meanfield`. Arguments arrive checked and contiguous from the Python half
//! (`motile/__init__.py`), which names the argument and the expected shape in its errors; the
//! checks here are the second line (errors, never panics).

use motile_experiments::io::checkpoint;
use motile_experiments::io::rundir::RunDir;
use motile_experiments::run;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};

mod analysis;
mod rundir;

use analysis::{
    bingham_closure, l2_norm, msd, nufft1, nufft2, relative_entropy, velocity_autocorrelation,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rundir::{RunDirectory, open};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// Columns of a CSV file: names, units, values.
pub(crate) type Columns<'py> = (
    Vec<String>,
    Vec<String>,
    Vec<Bound<'py, numpy::PyArray1<f64>>>,
);

/// A radial correlation: radii and values.
pub(crate) type Radial<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
);

pub(crate) fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{e:#}"))
}

pub(crate) fn runtime_error(e: anyhow::Error) -> PyErr {
    PyRuntimeError::new_err(format!("{e:#}"))
}

/// A TOML value as a Python object.
fn toml_to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let list = PyList::empty(py);
            for x in a {
                list.append(toml_to_py(py, x)?)?;
            }
            list.into_any()
        }
        toml::Value::Table(t) => table_to_py(py, t)?.into_any(),
    })
}

pub(crate) fn table_to_py<'py>(py: Python<'py>, t: &toml::Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in t {
        d.set_item(k, toml_to_py(py, v)?)?;
    }
    Ok(d)
}

/// A Python object (dict, list, str, bool, int, float) as a TOML value; `at` names it in errors.
fn py_to_toml(obj: &Bound<'_, PyAny>, at: &str) -> PyResult<toml::Value> {
    if let Ok(b) = obj.extract::<bool>()
        && obj.is_instance_of::<pyo3::types::PyBool>()
    {
        return Ok(toml::Value::Boolean(b));
    }
    if obj.is_instance_of::<pyo3::types::PyInt>() {
        return Ok(toml::Value::Integer(obj.extract::<i64>()?));
    }
    if let Ok(f) = obj.extract::<f64>() {
        return Ok(toml::Value::Float(f));
    }
    if let Ok(s) = obj.extract::<String>() {
        return Ok(toml::Value::String(s));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, v) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| value_error(format!("{at}: keys must be strings")))?;
            let v = py_to_toml(&v, &format!("{at}.{k}"))?;
            t.insert(k, v);
        }
        return Ok(toml::Value::Table(t));
    }
    if let Ok(l) = obj.cast::<PyList>() {
        let mut a = Vec::new();
        for (i, v) in l.iter().enumerate() {
            a.push(py_to_toml(&v, &format!("{at}[{i}]"))?);
        }
        return Ok(toml::Value::Array(a));
    }
    Err(value_error(format!(
        "{at}: a value of type {} cannot go into a config (str, bool, int, float, dict, list)",
        obj.get_type().name()?
    )))
}

/// The config text of a dict.
fn config_text(config: &Bound<'_, PyDict>) -> PyResult<String> {
    let toml::Value::Table(t) = py_to_toml(config.as_any(), "config")? else {
        unreachable!("a dict is a table")
    };
    toml::to_string(&t).map_err(value_error)
}

/// Run `work` on its own thread while this one holds the interpreter only to forward progress
/// to `progress` and to notice KeyboardInterrupt, which asks the run to stop at the next step
/// boundary with a checkpoint (the CLI's SIGINT); the interrupt is raised once it has.
fn drive<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce() -> anyhow::Result<T> + Send + 'static,
) -> PyResult<T> {
    checkpoint::clear_stop();
    let (tx, rx) = mpsc::channel::<(u64, u64, f64)>();
    run::set_progress_hook(Some(Box::new(move |p, l, t| {
        let _ = tx.send((p, l, t));
    })));
    let handle = std::thread::spawn(work);
    let mut pending: Option<PyErr> = None;
    loop {
        let finished = handle.is_finished();
        let mut last = None;
        while let Ok(m) = rx.try_recv() {
            last = Some(m);
        }
        if let (Some((p, l, t)), Some(cb)) = (last, &progress)
            && pending.is_none()
            && let Err(e) = cb.call1(py, (p, l, t))
        {
            // A failing callback stops the run like an interrupt, then its error is raised.
            checkpoint::request_stop(checkpoint::STOP_BY_CALLER);
            pending = Some(e);
        }
        if finished {
            break;
        }
        py.detach(|| std::thread::sleep(Duration::from_millis(20)));
        if pending.is_none()
            && let Err(e) = py.check_signals()
        {
            checkpoint::request_stop(2);
            pending = Some(e);
        }
    }
    run::set_progress_hook(None);
    let result = handle
        .join()
        .map_err(|_| PyRuntimeError::new_err("the run's thread panicked"))?;
    checkpoint::clear_stop();
    if let Some(e) = pending {
        if let Err(r) = &result {
            // The checkpoint the stop wrote, for the interrupt's message.
            if e.is_instance_of::<PyKeyboardInterrupt>(py) {
                let said = match r.downcast_ref::<checkpoint::Interrupted>() {
                    Some(i) => format!(
                        "interrupted at {}; checkpoint written to {}. Continue with motile.resume({:?})",
                        i.at,
                        i.checkpoint.display(),
                        i.run_dir.display().to_string()
                    ),
                    None => format!("{r:#}"),
                };
                return Err(PyKeyboardInterrupt::new_err(said));
            }
        }
        return Err(e);
    }
    result.map_err(runtime_error)
}

/// A summary of a finished invocation as a dict.
fn summary<'py>(
    py: Python<'py>,
    steps: u64,
    seconds: f64,
    out: &Path,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("steps", steps)?;
    d.set_item("seconds", seconds)?;
    d.set_item("path", out.display().to_string())?;
    Ok(d)
}

/// Start a run of `model` ("particle" or "meanfield") with the keys of `config` (a dict, every
/// key optional, as a config file's) in the new directory `out`, through the CLI's run loop.
#[pyfunction]
#[pyo3(signature = (model, config, out, progress=None))]
fn run_model<'py>(
    py: Python<'py>,
    model: &str,
    config: &Bound<'py, PyDict>,
    out: PathBuf,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let text = config_text(config)?;
    let label = Path::new("config");
    let cwd = std::env::current_dir().map_err(value_error)?;
    match model {
        "particle" => {
            use motile_experiments::run::particle::{
                ParticleRunConfig, parse_config, run_particle,
            };
            let mut cfg = parse_config(&text, label).map_err(|e| value_error(format!("{e:#}")))?;
            ParticleRunConfig::resolve_paths(&mut cfg, &cwd);
            cfg.validate().map_err(value_error)?;
            let o = out.clone();
            let s = drive(py, progress, move || run_particle(&cfg, &o, false))?;
            summary(py, s.steps, s.seconds, &out)
        }
        "meanfield" => {
            use motile_experiments::run::meanfield::{
                MeanFieldRunConfig, parse_config, run_meanfield,
            };
            let mut cfg = parse_config(&text, label).map_err(|e| value_error(format!("{e:#}")))?;
            MeanFieldRunConfig::resolve_paths(&mut cfg, &cwd);
            let o = out.clone();
            let s = drive(py, progress, move || run_meanfield(&cfg, &o, false))?;
            summary(py, s.steps, s.seconds, &out)
        }
        other => Err(value_error(format!(
            "model = \"{other}\" is not one of \"particle\", \"meanfield\""
        ))),
    }
}

/// Continue the run in `path` from its newest valid checkpoint.
#[pyfunction]
#[pyo3(signature = (path, progress=None))]
fn resume<'py>(
    py: Python<'py>,
    path: PathBuf,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let model = RunDir::open(&path)
        .and_then(|d| d.header())
        .map_err(value_error)?
        .model;
    let p = path.clone();
    match model.as_str() {
        "particle" => {
            let s = drive(py, progress, move || {
                motile_experiments::run::particle::resume_particle(&p, false)
            })?;
            summary(py, s.steps, s.seconds, &path)
        }
        "meanfield" => {
            let s = drive(py, progress, move || {
                motile_experiments::run::meanfield::resume_meanfield(&p, false)
            })?;
            summary(py, s.steps, s.seconds, &path)
        }
        other => Err(value_error(format!(
            "{}: a run of model \"{other}\" cannot be resumed",
            path.display()
        ))),
    }
}

/// Run the scene `name` (built in, or a scene file) into `out`, only the runs `only` if given;
/// returns the scene's Markdown report.
#[pyfunction]
#[pyo3(signature = (name, out, only=None, progress=None))]
fn run_scene(
    py: Python<'_>,
    name: &str,
    out: PathBuf,
    only: Option<Vec<String>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    use motile_experiments::campaign::scene::{load_scene, run_scene as run};
    let scene = load_scene(name).map_err(|e| value_error(format!("{e:#}")))?;
    let only = only.unwrap_or_default();
    drive(py, progress, move || {
        run(&scene, &out, &only, false, &mut |_| {}).map(|r| r.markdown)
    })
}

/// The compiled half of `motile`.
#[pymodule]
fn _motile(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<RunDirectory>()?;
    m.add_function(wrap_pyfunction!(open, m)?)?;
    m.add_function(wrap_pyfunction!(run_model, m)?)?;
    m.add_function(wrap_pyfunction!(resume, m)?)?;
    m.add_function(wrap_pyfunction!(run_scene, m)?)?;
    m.add_function(wrap_pyfunction!(nufft1, m)?)?;
    m.add_function(wrap_pyfunction!(nufft2, m)?)?;
    m.add_function(wrap_pyfunction!(velocity_autocorrelation, m)?)?;
    m.add_function(wrap_pyfunction!(l2_norm, m)?)?;
    m.add_function(wrap_pyfunction!(msd, m)?)?;
    m.add_function(wrap_pyfunction!(bingham_closure, m)?)?;
    m.add_function(wrap_pyfunction!(relative_entropy, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
