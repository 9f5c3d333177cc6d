//! posereg's Python package, its native part (`posereg._posereg`): the whole registration on
//! flat arrays, the GIL released while it runs. The Python side (python/posereg/__init__.py)
//! turns nibabel-style arrays with affines and SimpleITK images into these and back.

use numpy::{IntoPyArray, PyReadonlyArray1};
use posereg::device::{open_backend, DeviceChoice, DeviceWanted};
use posereg::io::config::parse_options;
use posereg::io::field::flip_ras_lps;
use posereg::pipeline::inputs::{check_pair, Pair, PairPaths};
use posereg::pipeline::register::RegisterOptions;
use posereg::progress::{Progress, Silent};
use posereg::registration::{register_pair, Request};
use posereg::{Affine, Field, Grid, Image};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::Path;

/// An image as Python hands it over: voxels x-fastest, dims, voxel → world RAS affine.
type Flat<'py, T> = (PyReadonlyArray1<'py, T>, [usize; 3], [[f64; 4]; 4]);

/// Progress as lines on stderr.
struct Lines;

impl Progress for Lines {
    fn begin(&self, stage: &str, _steps: usize) {
        eprintln!("posereg: {stage}");
    }
    fn step(&self, detail: &str) {
        eprintln!("posereg:   {detail}");
    }
    fn end(&self) {}
}

fn image<T: Clone + numpy::Element>((data, dims, affine): Flat<T>) -> PyResult<Image<T>> {
    let grid = Grid::new(dims, Affine::from_fn(|r, c| affine[r][c])).map_err(failed)?;
    Image::from_data(grid, data.as_slice()?.to_vec()).map_err(failed)
}

fn failed(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A field's vectors flat, 3 per voxel, LPS as field.nii.gz holds them.
fn lps(field: &Field) -> Vec<f32> {
    field.data.iter().flat_map(|v| flip_ras_lps(*v)).collect()
}

/// What one registration gives back, before it becomes Python objects.
struct Done {
    warped: Vec<f32>,
    field: Vec<f32>,
    inverse_field: Vec<f32>,
    jacobian: Vec<f32>,
    transforms: String,
    kinematics: Option<String>,
    report: String,
}

/// Registers `source` (with `labels`) to `target`. `settings`: a settings file's content as
/// JSON (the keys `posereg register --help` lists); `device`: cpu, gpu or auto; `threads`: CPU
/// threads (0: every core). Returns a dict of flat arrays (x-fastest; fields 3 LPS values per
/// voxel) and JSON texts (transforms, kinematics, report).
#[pyfunction]
#[pyo3(signature = (source, labels, target, settings, device, threads, progress))]
#[allow(clippy::too_many_arguments)] // the Python wrapper's one call
fn register_flat<'py>(
    py: Python<'py>,
    source: Flat<'py, f32>,
    labels: Flat<'py, u16>,
    target: Flat<'py, f32>,
    settings: &str,
    device: &str,
    threads: usize,
    progress: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let names = PairPaths {
        source: Path::new("source"),
        labels: Path::new("source_labels"),
        target: Path::new("target"),
    };
    let options: RegisterOptions =
        parse_options(Path::new("settings.json"), settings).map_err(failed)?;
    let pair = check_pair(
        image(source)?,
        image(labels)?,
        image(target)?,
        names,
        &options.init.chain,
    )
    .map_err(failed)?;
    let kind = match device {
        "cpu" => DeviceChoice::Cpu,
        "gpu" => DeviceChoice::Gpu,
        "auto" => DeviceChoice::Auto,
        other => return Err(failed(format!("device {other:?} is not cpu, gpu or auto"))),
    };
    let wanted = DeviceWanted {
        kind,
        adapter: None,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(failed)?;
    let done = py
        .detach(|| pool.install(|| run(&pair, (&options, names), &wanted, progress)))
        .map_err(failed)?;
    let out = PyDict::new(py);
    out.set_item("warped", done.warped.into_pyarray(py))?;
    out.set_item("field", done.field.into_pyarray(py))?;
    out.set_item("inverse_field", done.inverse_field.into_pyarray(py))?;
    out.set_item("jacobian", done.jacobian.into_pyarray(py))?;
    out.set_item("transforms", done.transforms)?;
    out.set_item("kinematics", done.kinematics)?;
    out.set_item("report", done.report)?;
    Ok(out)
}

/// The registration, its kinematics and its report (the library's one entry, as the command
/// line's), without the GIL.
fn run(
    pair: &Pair,
    (options, names): (&RegisterOptions, PairPaths),
    wanted: &DeviceWanted,
    progress: bool,
) -> posereg::Result<Done> {
    let (opened, _) = open_backend(wanted)?;
    let shown: &dyn Progress = if progress { &Lines } else { &Silent };
    let request = Request {
        pair,
        names,
        options,
        start: None,
        target_mask: None,
        side: None,
        inputs: serde_json::json!({ "python": "arrays handed to posereg.register" }),
        keep_initial_field: false,
    };
    let done = register_pair(&opened, request, shown)?;
    done.kinematics_warnings.iter().for_each(|w| shown.step(w));
    let kinematics =
        (done.kinematics.as_ref()).map(|k| serde_json::to_string(k).unwrap_or_default());
    let transforms = serde_json::to_string(&done.result.transforms(options)).unwrap_or_default();
    Ok(Done {
        field: lps(&done.result.field),
        inverse_field: lps(&done.result.inverse),
        warped: done.result.warped.data,
        jacobian: done.result.jacobian.data,
        transforms,
        kinematics,
        report: done.report.json.to_string(),
    })
}

/// The native module.
#[pymodule]
fn _posereg(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(register_flat, m)?)?;
    Ok(())
}
