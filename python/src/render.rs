//! Rendering scene files from Python (`glint.render`, `glint.write_exr`, `glint.write_png` in
//! `glint/__init__.py`), and reading map images as the tracer does (`glint.read_map_image`): glint-tracer's render job, the one `cargo xtask render` runs, so a
//! frame or a crop rendered here is the command line's bit for bit. The GIL is released while
//! a frame renders, and Ctrl-C stops it ([`crate::run_watched`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, PoisonError};
use std::time::SystemTime;

use glam::DVec3;
use glint_tracer::image::{PngValues, RgbImage};
use glint_tracer::job::{RenderJob, RenderOptions, display_image};
use glint_tracer::{Bloom, PixelBounds, RenderSettings, TracerError};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// A tracer error as the Python exception a caller expects: `OSError` when an output cannot be
/// written, `ValueError` for everything about the input (scene file, assets, settings,
/// camera), with the tracer's message (file, field, problem).
fn python_error(error: &TracerError) -> PyErr {
    match error {
        TracerError::Output { .. } => PyOSError::new_err(error.to_string()),
        _ => PyValueError::new_err(error.to_string()),
    }
}

/// A scene file loaded with its options, and what it was loaded from: the scene file and its
/// assets with their sizes and modification times.
struct LoadedJob {
    path: PathBuf,
    options: RenderOptions,
    stamps: Vec<(PathBuf, Option<(u64, SystemTime)>)>,
    job: RenderJob,
}

/// A file's size and modification time, if it can be inspected.
fn stamp(path: &Path) -> Option<(u64, SystemTime)> {
    let metadata = std::fs::metadata(path).ok()?;
    Some((metadata.len(), metadata.modified().ok()?))
}

impl LoadedJob {
    fn load(path: &Path, options: RenderOptions) -> Result<Self, TracerError> {
        // Stamped before reading, so that a file changed while it loads counts as changed.
        let before = stamp(path);
        let job = RenderJob::load(path, options)?;
        let mut stamps = vec![(path.to_path_buf(), before)];
        stamps.extend(job.scene.assets.iter().map(|a| (a.clone(), stamp(a))));
        Ok(Self {
            path: path.to_path_buf(),
            options,
            stamps,
            job,
        })
    }

    /// Whether this job is what loading `path` with `options` would build now.
    fn is_current(&self, path: &Path, options: &RenderOptions) -> bool {
        self.path == path
            && self.options == *options
            && self.stamps.iter().all(|(file, was)| {
                let now = stamp(file);
                now.is_some() && now == *was
            })
    }
}

/// The last scene a render loaded, kept for the next render of the same file with the same
/// options: a farm worker renders many tiles of one scene, and loading (parsing, the BVH, the
/// prior run) would otherwise be paid per tile. A job renders every frame as a fresh one would
/// (per-frame particle sets are rebuilt from the scene's materials), so reuse never changes an
/// image. The scene is loaded again when the file or any asset it read changed size or
/// modification time. One job at most: memory stays that of one scene.
///
/// The lock is taken only with the GIL held and never across a render: `os.fork` holds the
/// GIL too, so a forked child never inherits it locked.
static LAST_JOB: Mutex<Option<LoadedJob>> = Mutex::new(None);

/// The cached job if it is current for `path` and `options` (taking it out of the cache).
fn take_cached_job(path: &Path, options: &RenderOptions) -> Option<LoadedJob> {
    let mut last = LAST_JOB.lock().unwrap_or_else(PoisonError::into_inner);
    last.take()
        .filter(|loaded| loaded.is_current(path, options))
}

/// Renders frame `frame` of the scene file at `scene` with the given overrides; returns the
/// image of the pixel bounds as a float32 array of shape (height, width, 3) and the render's
/// summary as JSON text (what `cargo xtask render` writes beside its images).
#[pyfunction]
#[pyo3(signature = (scene, frame, pixel_bounds, resolution, spp, threads, smooth))]
#[allow(clippy::too_many_arguments)]
fn render_scene<'py>(
    py: Python<'py>,
    scene: PathBuf,
    frame: i64,
    pixel_bounds: Option<[u32; 4]>,
    resolution: Option<(u32, u32)>,
    spp: Option<u32>,
    threads: Option<usize>,
    smooth: bool,
) -> PyResult<(Bound<'py, PyAny>, String)> {
    let options = RenderOptions {
        samples_per_pixel: spp,
        resolution,
        pixel_bounds: pixel_bounds.map(|[x0, x1, y0, y1]| PixelBounds { x0, x1, y0, y1 }),
        smooth,
        ..RenderOptions::default()
    };
    let pool = match threads {
        None => crate::process_pool()?,
        // At most MAX_THREADS, checked before any thread starts.
        Some(count) => std::sync::Arc::new(
            glint_eval::batch::thread_pool(Some(count), |i| format!("glint-render-{i}")).map_err(
                |e| match glint_eval::batch::thread_count(Some(count)) {
                    Err(_) => PyValueError::new_err(e),
                    Ok(_) => PyRuntimeError::new_err(e),
                },
            )?,
        ),
    };
    let thread_count = pool.current_num_threads();
    let cancelled = AtomicBool::new(false);
    // Taken from the cache with the GIL held (see `LAST_JOB`), rendered without it.
    // Loaded jobs are kept without bounds: every tile of a scene shares one.
    let whole = RenderOptions {
        pixel_bounds: None,
        ..options
    };
    let cached = take_cached_job(&scene, &whole);
    let result = crate::run_watched(py, &cancelled, || {
        let mut loaded = match cached {
            Some(loaded) => loaded,
            None => LoadedJob::load(&scene, whole)?,
        };
        loaded.job.set_pixel_bounds(options.pixel_bounds)?;
        let output = pool.install(|| loaded.job.render_frame(frame, &|_, _| {}, &cancelled))?;
        let summary = loaded.job.summary(&output, thread_count).to_string();
        Ok::<_, TracerError>((output, summary, loaded))
    })?;
    let result = result.map(|(output, summary, loaded)| {
        *LAST_JOB.lock().unwrap_or_else(PoisonError::into_inner) = Some(loaded);
        (output, summary)
    });
    let (output, summary) = result.map_err(|e| python_error(&e))?;
    let (width, height) = (output.image.width, output.image.height);
    let flat: Vec<f32> = output
        .image
        .pixels
        .iter()
        .flat_map(|p| p.as_vec3().to_array())
        .collect();
    let image = PyArray1::from_vec(py, flat).reshape([height, width, 3])?;
    Ok((image.into_any(), summary))
}

/// The (height, width, 3) float32 array as an image, refusing non-finite pixels.
fn image_from(array: &PyReadonlyArray3<'_, f32>) -> PyResult<RgbImage> {
    let view = array.as_array();
    let (height, width, channels) = view.dim();
    if channels != 3 || width == 0 || height == 0 {
        return Err(PyValueError::new_err(format!(
            "image must have shape (height, width, 3) with height, width ≥ 1, not {:?}",
            view.shape()
        )));
    }
    let mut image = RgbImage::filled(width, height, DVec3::ZERO);
    for ((y, x), pixel) in image
        .pixels
        .iter_mut()
        .enumerate()
        .map(|(i, p)| ((i / width, i % width), p))
    {
        let rgb = [view[[y, x, 0]], view[[y, x, 1]], view[[y, x, 2]]];
        if !rgb.iter().all(|c| c.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "image pixel (row {y}, column {x}) is {rgb:?}: not finite"
            )));
        }
        *pixel = DVec3::new(rgb[0].into(), rgb[1].into(), rgb[2].into());
    }
    Ok(image)
}

/// Writes `image` as the tracer writes a linear 32-bit float EXR.
#[pyfunction]
fn write_exr(py: Python<'_>, path: PathBuf, image: PyReadonlyArray3<'_, f32>) -> PyResult<()> {
    let image = image_from(&image)?;
    py.detach(|| image.write_exr(&path))
        .map_err(|e| python_error(&e))
}

/// Writes `image` as the tracer writes its PNG: bloom (threshold, radius, strength) if given,
/// then exposure 2^`exposure`, clamped, sRGB-encoded to 8 bits.
#[pyfunction]
#[pyo3(signature = (path, image, exposure, bloom))]
fn write_png(
    py: Python<'_>,
    path: PathBuf,
    image: PyReadonlyArray3<'_, f32>,
    exposure: f64,
    bloom: Option<(f64, f64, f64)>,
) -> PyResult<()> {
    let image = image_from(&image)?;
    if !exposure.is_finite() {
        return Err(PyValueError::new_err(format!(
            "exposure must be finite, not {exposure}"
        )));
    }
    let bloom = match bloom {
        None => None,
        Some((threshold, radius, strength)) => {
            let valid = threshold >= 0.0
                && threshold.is_finite()
                && radius > 0.0
                && radius <= 256.0
                && strength >= 0.0
                && strength.is_finite();
            if !valid {
                return Err(PyValueError::new_err(format!(
                    "bloom needs threshold ≥ 0, radius in (0, 256] and strength ≥ 0, all finite; got ({threshold}, {radius}, {strength})"
                )));
            }
            Some(Bloom {
                threshold,
                radius,
                strength,
            })
        }
    };
    let settings = RenderSettings {
        bloom,
        exposure,
        ..RenderSettings::default()
    };
    py.detach(|| display_image(&image, &settings).write_png(&path, exposure))
        .map_err(|e| python_error(&e))
}

/// Checks the camera of the scene file `scene` at every frame of `frames` (loaded with the
/// overrides `resolution` and `spp`, as `render_scene` loads it, and kept for the renders that
/// follow), as `cargo xtask render --frames` does before it renders any: keyframes valid alone
/// may interpolate to a degenerate pose between them. `ValueError` names the first frame at
/// fault (the tracer's message).
#[pyfunction]
#[pyo3(signature = (scene, frames, resolution, spp))]
fn check_camera_frames(
    py: Python<'_>,
    scene: PathBuf,
    frames: Vec<i64>,
    resolution: Option<(u32, u32)>,
    spp: Option<u32>,
) -> PyResult<()> {
    let options = RenderOptions {
        samples_per_pixel: spp,
        resolution,
        ..RenderOptions::default()
    };
    let cached = take_cached_job(&scene, &options);
    let loaded = py
        .detach(|| match cached {
            Some(loaded) => Ok(loaded),
            None => LoadedJob::load(&scene, options),
        })
        .map_err(|e| python_error(&e))?;
    let problem = frames.iter().find_map(|&frame| {
        loaded
            .job
            .scene
            .camera
            .checked_pose(frame as f64)
            .err()
            .map(|problem| TracerError::Camera {
                frame: frame as f64,
                problem,
            })
    });
    *LAST_JOB.lock().unwrap_or_else(PoisonError::into_inner) = Some(loaded);
    match problem {
        Some(error) => Err(python_error(&error)),
        None => Ok(()),
    }
}

/// Reads the image file `path` as glint-tracer reads a scene file's map (`density_texture`,
/// `alpha_texture`, `tint_texture`), under the same limits: a PNG or OpenEXR file of at most
/// `limits::MAX_IMAGE_FILE_BYTES`, its size checked from the header against
/// `limits::MAX_IMAGE_SIDE` and `limits::MAX_IMAGE_PIXELS` before its pixels are decoded, every
/// pixel finite. A PNG's values are read linearly (k/255, k/65535) for data (`colour` false)
/// and decoded from sRGB for a colour. The texels as (height, width, 3) float64, rows from the
/// image's top; the tracer's message as `ValueError`.
#[pyfunction]
#[pyo3(signature = (path, colour))]
fn read_map_image<'py>(
    py: Python<'py>,
    path: PathBuf,
    colour: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let values = if colour {
        PngValues::Srgb
    } else {
        PngValues::Linear
    };
    let image = py
        .detach(|| RgbImage::load_as(&path, values))
        .map_err(|e| python_error(&e))?;
    let (width, height) = (image.width, image.height);
    let flat: Vec<f64> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
    drop(image);
    Ok(PyArray1::from_vec(py, flat)
        .reshape([height, width, 3])?
        .into_any())
}

/// Adds the rendering functions to the native module.
pub(crate) fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(render_scene, module)?)?;
    module.add_function(wrap_pyfunction!(write_exr, module)?)?;
    module.add_function(wrap_pyfunction!(write_png, module)?)?;
    module.add_function(wrap_pyfunction!(read_map_image, module)?)?;
    module.add_function(wrap_pyfunction!(check_camera_frames, module)?)?;
    Ok(())
}
