//! posereg's Python package, its native part (`posereg._posereg`): the whole registration on
//! flat arrays or on files, the GIL released while it runs. The Python side (python/posereg/__init__.py)
//! turns nibabel-style arrays with affines and SimpleITK images into these and back.

use numpy::{IntoPyArray, PyReadonlyArray1};
use posereg::device::{open_backend, DeviceChoice, DeviceWanted};
use posereg::io::config::options_from_json;
use posereg::io::field::flip_ras_lps;
use posereg::jobs::reporter::Reporter;
use posereg::pipeline::inputs::{check_pair, load_pair, Pair, PairPaths};
use posereg::pipeline::register::RegisterOptions;
use posereg::progress::{Progress, Silent};
use posereg::registration::{file_inputs, register_pair, Request};
use posereg::{Affine, Field, Grid, Image};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::Path;

/// An image as Python hands it over: voxels x-fastest, dims, voxel → world RAS affine.
type Flat<'py, T> = (PyReadonlyArray1<'py, T>, [usize; 3], [[f64; 4]; 4]);

/// The image an argument holds; its problems are named after the argument.
fn image<T: Clone + numpy::Element>(
    name: &Path,
    (data, dims, affine): Flat<T>,
) -> PyResult<Image<T>> {
    let named = |e: posereg::Error| failed(format!("{}: {e}", name.display()));
    let grid = Grid::new(dims, Affine::from_fn(|r, c| affine[r][c])).map_err(named)?;
    Image::from_data(grid, data.as_slice()?.to_vec()).map_err(named)
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

/// Where the registration runs: the device (cpu, gpu or auto), CPU threads (0: every core),
/// and whether progress lines go to stderr.
type Asked<'a> = (&'a str, usize, bool);

/// Registers `source` (with `labels`) to `target`, three images handed over as arrays, with
/// `settings` a settings file's content as JSON (the keys `posereg register --help` lists). Returns
/// a dict of flat arrays (x-fastest; fields 3 LPS values per voxel) and JSON texts
/// (transforms, kinematics, report).
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
    let options = settings_of(settings)?;
    let source = image(names.source, source)?;
    let labels = image(names.labels, labels)?;
    let target = image(names.target, target)?;
    let pair = check_pair(source, labels, target, names, &options.init.chain).map_err(failed)?;
    registered(
        py,
        &pair,
        (&options, names, false),
        (device, threads, progress),
    )
}

/// Registers the scans in three NIfTI files, read and checked as `posereg register` reads
/// them (headers against each other first, then the voxels). Returns what `register_flat`
/// returns, with each scan's grid: `source_grid` and `target_grid`, (dims, RAS affine).
#[pyfunction]
#[pyo3(signature = (source, labels, target, settings, device, threads, progress))]
#[allow(clippy::too_many_arguments)] // the Python wrapper's one call
fn register_files<'py>(
    py: Python<'py>,
    source: &str,
    labels: &str,
    target: &str,
    settings: &str,
    device: &str,
    threads: usize,
    progress: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let names = PairPaths {
        source: Path::new(source),
        labels: Path::new(labels),
        target: Path::new(target),
    };
    let options = settings_of(settings)?;
    let pair = load_pair(names, &options.init.chain).map_err(failed)?;
    let out = registered(
        py,
        &pair,
        (&options, names, true),
        (device, threads, progress),
    )?;
    for (key, grid) in [
        ("source_grid", &pair.source.grid),
        ("target_grid", &pair.target.grid),
    ] {
        let affine: Vec<Vec<f64>> = (0..4)
            .map(|r| (0..4).map(|c| grid.affine[(r, c)]).collect())
            .collect();
        out.set_item(key, (grid.dims.to_vec(), affine))?;
    }
    Ok(out)
}

/// The settings the keyword arguments hold, checked, errors naming them as such.
fn settings_of(settings: &str) -> PyResult<RegisterOptions> {
    options_from_json("the settings keyword arguments", settings).map_err(failed)
}

/// Runs the registration of a checked pair on the device asked for, without the GIL, and
/// turns what it gives back into a dict.
fn registered<'py>(
    py: Python<'py>,
    pair: &Pair,
    (options, names, from_files): (&RegisterOptions, PairPaths, bool),
    (device, threads, progress): Asked,
) -> PyResult<Bound<'py, PyDict>> {
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
        .detach(|| pool.install(|| run(pair, (options, names, from_files), &wanted, progress)))
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
    (options, names, from_files): (&RegisterOptions, PairPaths, bool),
    wanted: &DeviceWanted,
    progress: bool,
) -> posereg::Result<Done> {
    let (opened, _) = open_backend(wanted)?;
    let shown: &dyn Progress = if progress {
        &Reporter::new(false)
    } else {
        &Silent
    };
    let request = Request {
        pair,
        names,
        options,
        start: None,
        target_mask: None,
        side: None,
        inputs: match from_files {
            true => file_inputs(names, (None, None), None),
            false => serde_json::json!({ "python": "arrays handed to posereg.register" }),
        },
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
    m.add_function(wrap_pyfunction!(register_files, m)?)?;
    Ok(())
}
