//! `penumbra._penumbra`: the compiled half of the Python package `penumbra` (the other half,
//! python/penumbra/__init__.py, re-exports it and adds the DataFrame form of `converge`).
//!
//! The bindings call the same library functions as the CLI, with the same defaults, so that a
//! render from Python is bit-identical to `penumbra render` with the same scene, spp and seed,
//! and `compare` returns what `compare --json` prints. Every library error becomes a
//! `penumbra.PenumbraError` carrying the CLI's one-line message; bad Python arguments are
//! `ValueError`s. Renders run with the GIL released and stop on Ctrl-C (`KeyboardInterrupt`)
//! after the pass under way.

use numpy::{
    AllowTypeChange, PyArray1, PyArray3, PyArrayLike2, PyArrayLike3, PyArrayMethods,
    PyUntypedArrayMethods,
};
use penumbra::io::exr::{self, Attribute, RgbImage};
use penumbra::progressive::{self, ProgressiveSettings};
use penumbra::study::{compare as cmp, experiment as ex};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

create_exception!(
    _penumbra,
    PenumbraError,
    PyException,
    "A scene, image or argument penumbra refuses; the message is the CLI's one line."
);

fn err(e: penumbra::Error) -> PyErr {
    PenumbraError::new_err(e.to_string())
}

/// How often a waiting render checks for Ctrl-C.
const SIGNAL_POLL: Duration = Duration::from_millis(20);

/// Runs `work` on a thread of its own with the GIL released, checking for signals (Ctrl-C)
/// every few milliseconds. On a signal, `stop` is set, the work is awaited (it ends after the
/// pass under way) and the signal's exception (`KeyboardInterrupt`) is returned.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    stop: &AtomicBool,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|s| {
        let handle = s.spawn(work);
        loop {
            let finished = py.detach(|| {
                let start = Instant::now();
                while !handle.is_finished() && start.elapsed() < SIGNAL_POLL {
                    std::thread::sleep(Duration::from_millis(1));
                }
                handle.is_finished()
            });
            if finished {
                break;
            }
            if let Err(e) = py.check_signals() {
                stop.store(true, Ordering::Relaxed);
                let _ = py.detach(|| handle.join());
                return Err(e);
            }
        }
        py.detach(|| handle.join())
            .map_err(|_| PenumbraError::new_err("internal error: the render thread panicked"))
    })
}

/// A define's value as the scene file reads it: booleans as `true`/`false`, numbers and
/// strings as Python prints them.
fn define_value(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(b) = v.extract::<bool>() {
        return Ok(if b { "true" } else { "false" }.into());
    }
    Ok(v.str()?.to_string())
}

fn defines_of(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, String)>> {
    let mut out = Vec::new();
    if let Some(d) = kwargs {
        for (k, v) in d.iter() {
            out.push((k.extract::<String>()?, define_value(&v)?));
        }
    }
    Ok(out)
}

/// An (H, W, 3) float32 array from an image's pixels.
fn to_array<'py>(
    py: Python<'py>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let flat: Vec<f32> = rgb.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([height, width, 3])
}

/// The pixels of an (H, W, 3) array (any float or int dtype; converted to float32).
fn from_array(
    name: &str,
    a: &PyArrayLike3<'_, f32, AllowTypeChange>,
) -> PyResult<(usize, usize, Vec<[f32; 3]>)> {
    let shape = a.shape();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected an array of shape (height, width, 3), got {shape:?}"
        )));
    }
    let (height, width) = (shape[0], shape[1]);
    let view = a.as_array();
    let mut rgb = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            rgb.push([view[[y, x, 0]], view[[y, x, 1]], view[[y, x, 2]]]);
        }
    }
    Ok((width, height, rgb))
}

/// The pixels of the variance array `name` of the image `of`, which is `size` (width, height).
fn variance_of(
    name: &str,
    of: &str,
    v: &PyArrayLike3<'_, f32, AllowTypeChange>,
    (width, height): (usize, usize),
) -> PyResult<Vec<[f32; 3]>> {
    let (vw, vh, var) = from_array(name, v)?;
    if (vw, vh) != (width, height) {
        return Err(PyValueError::new_err(format!(
            "{name} is {vw}x{vh}, {of} is {width}x{height}"
        )));
    }
    Ok(var)
}

/// An image given either as a path to an OpenEXR file or as an (H, W, 3) array with an
/// optional variance array of the same shape.
fn image_arg(
    name: &str,
    image: &Bound<'_, PyAny>,
    variance: Option<PyArrayLike3<'_, f32, AllowTypeChange>>,
) -> PyResult<(RgbImage, String)> {
    if let Ok(path) = image.extract::<PathBuf>() {
        if variance.is_some() {
            return Err(PyValueError::new_err(format!(
                "{name} is a file: its variance comes from its variance channels, not from \
                 var_{name}"
            )));
        }
        let img = exr::read(&path).map_err(err)?;
        return Ok((img, path.to_string_lossy().into_owned()));
    }
    let array: PyArrayLike3<'_, f32, AllowTypeChange> = image.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "{name}: expected a path to an OpenEXR file or an array of shape (height, width, 3)"
        ))
    })?;
    let (width, height, rgb) = from_array(name, &array)?;
    let variance = variance
        .map(|v| variance_of(&format!("var_{name}"), name, &v, (width, height)))
        .transpose()?;
    Ok((
        RgbImage {
            width,
            height,
            rgb,
            variance,
            attributes: BTreeMap::new(),
        },
        name.to_string(),
    ))
}

fn positive(name: &str, v: Option<f64>) -> PyResult<Option<f64>> {
    match v {
        Some(x) if !(x > 0.0 && x.is_finite()) => Err(PyValueError::new_err(format!(
            "{name} must be a positive number, got {x}"
        ))),
        _ => Ok(v),
    }
}

fn json_to_py<'py>(py: Python<'py>, json: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (json,))
}

/// A loaded scene (`penumbra.load`). Render it with `render`; `width`, `height`, `spp`
/// (the sampler's sample_count), `seed` and `warnings` describe it; `stats` holds the last
/// render's statistics.
#[pyclass(module = "penumbra")]
struct Scene {
    path: PathBuf,
    defines: Vec<(String, String)>,
    job: penumbra::render::Job,
    /// The sampler the scene file declares (a render with another spp replaces it).
    sampler: penumbra::sampler::Sampler,
    stats: Option<Py<PyDict>>,
}

#[pymethods]
impl Scene {
    #[getter]
    fn width(&self) -> usize {
        self.job.scene.width
    }
    #[getter]
    fn height(&self) -> usize {
        self.job.scene.height
    }
    /// The scene's samples per pixel (its sampler's sample_count).
    #[getter]
    fn spp(&self) -> u32 {
        self.job.scene.sample_count
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.job.scene.seed
    }
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.job.scene.warnings.clone()
    }
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }
    /// The statistics of the last render (spp, seconds, paths, stop_reason, ...), or None.
    #[getter]
    fn stats(&self, py: Python<'_>) -> Option<Py<PyDict>> {
        self.stats.as_ref().map(|d| d.clone_ref(py))
    }

    fn __repr__(&self) -> String {
        format!(
            "<penumbra.Scene {} {}x{}, {} spp>",
            self.path.display(),
            self.job.scene.width,
            self.job.scene.height,
            self.job.scene.sample_count
        )
    }

    /// Renders the scene: an (H, W, 3) float32 array of linear RGB, or `(image, variance)`
    /// with `variance=True` (the per-sample variance of each pixel, as `--variance` writes).
    /// `spp` defaults to the scene's (rounded by its sampler as the CLI rounds it), `seed` to
    /// the sampler's; `threads` to one per core; `time_limit` (seconds) stops early. The
    /// same arguments give the same array as `penumbra render`, bit for bit, at any thread
    /// count. Ctrl-C raises KeyboardInterrupt after the pass under way.
    #[pyo3(signature = (spp=None, seed=None, threads=None, variance=false, time_limit=None))]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        spp: Option<u32>,
        seed: Option<u64>,
        threads: Option<usize>,
        variance: bool,
        time_limit: Option<f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if spp == Some(0) {
            return Err(PyValueError::new_err("spp must be at least 1"));
        }
        if threads == Some(0) {
            return Err(PyValueError::new_err("threads must be at least 1"));
        }
        let time_limit = positive("time_limit", time_limit)?.map(Duration::from_secs_f64);
        let spp = match spp {
            Some(n) => {
                let (rounded, warning) = self.job.scene.set_sample_count(n);
                if let Some(w) = warning {
                    let warnings = py.import("warnings")?;
                    warnings.call_method1("warn", (format!("{w} (spp)"),))?;
                }
                rounded
            }
            None => {
                self.job.scene.sampler = self.sampler;
                self.job.scene.sample_count
            }
        };
        let stop = Arc::new(AtomicBool::new(false));
        let settings = ProgressiveSettings {
            spp,
            seed: seed.unwrap_or(self.job.scene.seed),
            threads,
            time_limit,
            target_rel_error: None,
            checkpoint: None,
            // No checkpoints from Python: the hash only names them.
            scene_hash: 0,
            stop: Some(stop.clone()),
        };
        let job = &self.job;
        let (progress, reason) = run_interruptible(py, &stop, || {
            progressive::render_progressive(job, &settings, None, &|_| {})
        })?
        .map_err(err)?;
        let film = &progress.film;
        let stats = PyDict::new(py);
        stats.set_item("spp", progress.samples)?;
        stats.set_item("seed", settings.seed)?;
        stats.set_item("seconds", progress.stats.seconds)?;
        stats.set_item("paths", progress.stats.paths)?;
        stats.set_item("mpaths_per_second", progress.stats.mpaths_per_second())?;
        stats.set_item("nonfinite_samples", progress.stats.nonfinite)?;
        stats.set_item("stop_reason", reason.as_str())?;
        self.stats = Some(stats.unbind());
        let image = to_array(py, film.width, film.height, &film.image())?;
        if variance {
            let var = to_array(py, film.width, film.height, &film.sample_variance())?;
            Ok(PyTuple::new(py, [image.into_any(), var.into_any()])?.into_any())
        } else {
            Ok(image.into_any())
        }
    }

    /// Casts a batch of rays through the scene's hierarchy (the traversal the integrators
    /// use), as Mitsuba's `scene.ray_intersect_preliminary` (closest hit) or `scene.ray_test`
    /// (`any=True`) do. `origins` and `directions` are (N, 3) arrays; `tmax` bounds every
    /// ray (default: none). Returns `(values, seconds)`: per ray the distance of the nearest
    /// hit (inf on a miss), or with `any=True` 1.0 where something lies on the ray, else
    /// 0.0; and the seconds the traversal took on `threads` workers (default: one per core).
    #[pyo3(signature = (origins, directions, any=false, threads=None, tmax=None))]
    fn cast<'py>(
        &self,
        py: Python<'py>,
        origins: PyArrayLike2<'py, f32, AllowTypeChange>,
        directions: PyArrayLike2<'py, f32, AllowTypeChange>,
        any: bool,
        threads: Option<usize>,
        tmax: Option<f32>,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, f64)> {
        let (o, d) = (origins.as_array(), directions.as_array());
        if o.shape().len() != 2 || o.shape()[1] != 3 || o.shape() != d.shape() {
            return Err(PyValueError::new_err(format!(
                "origins and directions must both be (N, 3) arrays, got {:?} and {:?}",
                o.shape(),
                d.shape()
            )));
        }
        if threads == Some(0) {
            return Err(PyValueError::new_err("threads must be at least 1"));
        }
        let tmax = tmax.unwrap_or(f32::INFINITY);
        if tmax.is_nan() || tmax <= 0.0 {
            return Err(PyValueError::new_err("tmax must be positive"));
        }
        let v3 = |a: &numpy::ndarray::ArrayView2<f32>, i: usize| {
            glam::Vec3::new(a[[i, 0]], a[[i, 1]], a[[i, 2]])
        };
        let rays: Vec<penumbra::geometry::Ray> = (0..o.shape()[0])
            .map(|i| penumbra::geometry::Ray::new(v3(&o, i), v3(&d, i), tmax))
            .collect();
        let query = if any {
            penumbra::study::rays::Query::Any
        } else {
            penumbra::study::rays::Query::Closest
        };
        let scene = &self.job.scene;
        let (values, seconds) = py
            .detach(|| penumbra::study::rays::cast(scene, &rays, query, threads))
            .map_err(err)?;
        Ok((PyArray1::from_vec(py, values), seconds))
    }
}

/// Loads a Mitsuba 3 XML scene; keyword arguments set its `<default>` parameters as `-D`
/// does (`penumbra.load("cbox.xml", res=64, integrator="path")`). `mode` is `"rgb"` (the
/// default) or `"spectral"`, as `render --mode` (Mitsuba's `*_rgb` or `*_spectral` variants).
#[pyfunction]
#[pyo3(signature = (path, mode="rgb", **defines))]
fn load(path: PathBuf, mode: &str, defines: Option<&Bound<'_, PyDict>>) -> PyResult<Scene> {
    let defines = defines_of(defines)?;
    let mode = penumbra::spectrum::Mode::from_name(mode).ok_or_else(|| {
        pyo3::exceptions::PyValueError::new_err(format!(
            "mode '{mode}' is not \"rgb\" or \"spectral\""
        ))
    })?;
    let mut desc = penumbra::scene::Scene::load_description(&path, &defines).map_err(err)?;
    desc.mode = mode;
    let job = penumbra::render::Job::build(&desc).map_err(err)?;
    Ok(Scene {
        path,
        defines,
        sampler: job.scene.sampler,
        job,
        stats: None,
    })
}

/// Compares image `a` with the reference `b`: the dict `penumbra compare --json` prints
/// (RMSE, MSE, relative MSE, MAE, means, the per-pixel z-test, ...). Each image is a path to
/// an OpenEXR file (its spp and variance read from it, as the CLI does) or an (H, W, 3)
/// array with its spp and optional per-sample variance array.
#[pyfunction]
#[pyo3(signature = (a, b, spp_a=None, spp_b=None, var_a=None, var_b=None))]
fn compare<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
    spp_a: Option<f64>,
    spp_b: Option<f64>,
    var_a: Option<PyArrayLike3<'py, f32, AllowTypeChange>>,
    var_b: Option<PyArrayLike3<'py, f32, AllowTypeChange>>,
) -> PyResult<Bound<'py, PyAny>> {
    let spp_a = positive("spp_a", spp_a)?;
    let spp_b = positive("spp_b", spp_b)?;
    let (a, a_name) = image_arg("a", a, var_a)?;
    let (b, b_name) = image_arg("b", b, var_b)?;
    let alpha = penumbra::study::validation::ALPHA;
    let c = cmp::compare(&a, &b, spp_a, spp_b, alpha).map_err(err)?;
    let json = serde_json::to_string(&c.to_json(&a_name, &b_name, alpha, None))
        .map_err(|e| PenumbraError::new_err(e.to_string()))?;
    json_to_py(py, &json)
}

/// The convergence ladder of `penumbra converge`: renders `scene` (reloaded from its file
/// with its defines, and with each value of `sweep`, "NAME=v1,v2,...") at the cumulative
/// sample counts `spp`, for `seeds` seeds from `seed`, and measures each step against
/// `reference` (a path to an OpenEXR file, or an array with `reference_spp` and
/// `reference_variance`). Returns one dict per step.
#[pyfunction]
#[pyo3(signature = (scene, reference, spp, seeds=1, seed=None, sweep=None, threads=None,
                    max_seconds=None, reference_spp=None, reference_variance=None))]
#[allow(clippy::too_many_arguments)]
fn converge<'py>(
    py: Python<'py>,
    scene: PyRef<'py, Scene>,
    reference: &Bound<'py, PyAny>,
    spp: Vec<u32>,
    seeds: u32,
    seed: Option<u64>,
    sweep: Option<String>,
    threads: Option<usize>,
    max_seconds: Option<f64>,
    reference_spp: Option<f64>,
    reference_variance: Option<PyArrayLike3<'py, f32, AllowTypeChange>>,
) -> PyResult<Bound<'py, PyList>> {
    if spp.is_empty() || spp.contains(&0) || spp.windows(2).any(|w| w[0] >= w[1]) {
        return Err(PyValueError::new_err(
            "spp must be a non-empty increasing list of sample counts >= 1",
        ));
    }
    if seeds == 0 {
        return Err(PyValueError::new_err("seeds must be at least 1"));
    }
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads must be at least 1"));
    }
    let reference_spp = positive("reference_spp", reference_spp)?;
    let max_seconds = positive("max_seconds", max_seconds)?;
    let (image, _) = image_arg("reference", reference, reference_variance)?;
    let reference = ex::ReferenceImage {
        spp: reference_spp.or(image.spp()),
        image,
    };
    let sweep = sweep
        .as_deref()
        .map(ex::Sweep::parse)
        .transpose()
        .map_err(PenumbraError::new_err)?;
    let (variants, _) =
        ex::scene_variants(&scene.path, &scene.defines, sweep.as_ref()).map_err(err)?;
    let first_seed = seed.unwrap_or(variants[0].description.sensor.sampler.seed);
    let records = PyList::empty(py);
    for variant in &variants {
        let built = penumbra::render::Job::build(&variant.description).map_err(err)?;
        for k in 0..seeds as u64 {
            let seed = first_seed.wrapping_add(k);
            let run = py
                .detach(|| {
                    ex::run_one(
                        &built,
                        &spp,
                        seed,
                        threads,
                        &reference,
                        max_seconds,
                        &mut |_, _| {},
                    )
                })
                .map_err(err)?;
            for step in &run.steps {
                let d = PyDict::new(py);
                d.set_item("label", &variant.label)?;
                d.set_item("value", variant.value.as_deref())?;
                d.set_item("seed", seed)?;
                d.set_item("spp", step.spp)?;
                d.set_item("seconds", step.seconds)?;
                d.set_item("mpaths_per_second", step.mpaths_per_second)?;
                d.set_item("rmse", step.metrics.rmse)?;
                d.set_item("mse", step.metrics.mse)?;
                d.set_item("rel_mse", step.metrics.rel_mse)?;
                d.set_item("mae", step.metrics.mae)?;
                d.set_item("efficiency", step.efficiency)?;
                d.set_item("z_pass_rate", step.z_pass_rate)?;
                records.append(d)?;
            }
            // Ctrl-C between ladders.
            py.check_signals()?;
        }
    }
    Ok(records)
}

/// Reads an OpenEXR image: `(rgb, variance, attributes)`, with `rgb` an (H, W, 3) float32
/// array, `variance` the same from its `variance.R/G/B` channels or None, and `attributes`
/// its header attributes as strings (`spp`, `seed`, ...).
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyTuple>> {
    let img = exr::read(&path).map_err(err)?;
    let rgb = to_array(py, img.width, img.height, &img.rgb)?.into_any();
    let var = match &img.variance {
        Some(v) => to_array(py, img.width, img.height, v)?.into_any(),
        None => py.None().into_bound(py),
    };
    let attrs = PyDict::new(py);
    for (k, v) in &img.attributes {
        attrs.set_item(k, v)?;
    }
    PyTuple::new(py, [rgb, var, attrs.into_any()])
}

/// Writes an (H, W, 3) array as a float32 OpenEXR file (atomically), with an optional
/// variance array (channels `variance.R/G/B`) and header attributes (int, float or str
/// values; `spp` is what `compare` and `converge` read).
#[pyfunction]
#[pyo3(signature = (path, rgb, variance=None, attributes=None))]
fn write_exr(
    path: PathBuf,
    rgb: PyArrayLike3<'_, f32, AllowTypeChange>,
    variance: Option<PyArrayLike3<'_, f32, AllowTypeChange>>,
    attributes: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    let (width, height, pixels) = from_array("rgb", &rgb)?;
    let variance = variance
        .map(|v| variance_of("variance", "rgb", &v, (width, height)))
        .transpose()?;
    let mut attrs: Vec<(String, Attribute)> = Vec::new();
    if let Some(d) = attributes {
        for (k, v) in d.iter() {
            let name: String = k.extract()?;
            let value = if v.is_instance_of::<pyo3::types::PyBool>() {
                Attribute::Text(define_value(&v)?)
            } else if let Ok(i) = v.extract::<i32>() {
                Attribute::Int(i)
            } else if let Ok(f) = v.extract::<f64>() {
                Attribute::Float(f)
            } else if let Ok(s) = v.extract::<String>() {
                Attribute::Text(s)
            } else {
                return Err(PyValueError::new_err(format!(
                    "attribute {name}: expected an int, float or str"
                )));
            };
            attrs.push((name, value));
        }
    }
    let attrs: Vec<(&str, Attribute)> =
        attrs.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
    let image = RgbImage {
        width,
        height,
        rgb: pixels,
        variance,
        attributes: BTreeMap::new(),
    };
    exr::write(&path, &image, &attrs).map_err(err)
}

#[pymodule]
fn _penumbra(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", penumbra::VERSION)?;
    m.add("PenumbraError", m.py().get_type::<PenumbraError>())?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(converge, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(write_exr, m)?)?;
    Ok(())
}
