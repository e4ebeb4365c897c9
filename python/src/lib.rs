//! # glint-python: the Python module `glint._glint`
//!
//! **Invariant: this module adds transport only.** Every material and every row goes through
//! glint-eval, the contract of `docs/eval.md` that `cargo xtask eval` also uses, so the same
//! inputs give the same numbers bit for bit and the same error messages; every render goes
//! through glint-tracer's render job, as `cargo xtask render` does ([`render`]). The pure-Python
//! package `glint` (`glint/__init__.py`) holds the documented signatures and shapes; this
//! module takes C-contiguous float64 arrays of n rows and returns flat columns.
//!
//! Rows are answered in parallel with the GIL released by glint-eval's batch machinery (one
//! query scratch per worker thread, kept across calls; rows dispatched by footprint locality);
//! each row's answer depends only on the row, so the thread count never changes a result.
//! The worker threads belong to a pool of this process ([`process_pool`]), never rayon's
//! global pool: a child forked after the parent used the package (multiprocessing's default
//! on Linux) has none of the parent's threads, and a pool built before the fork would wait
//! for them forever.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use glint_brdf::{DVec3, DistributionKind, QueryScratch};
use glint_eval::{EvalColumns, EvalMaterial, EvalRow, MapSpec, MaterialSpec, uniforms_from_three};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

mod render;

/// A built glint material (see `glint.Material`).
#[pyclass(frozen, module = "glint._glint")]
struct Material {
    inner: EvalMaterial,
}

/// The rows of an (n, k) float64 array as `[f64; K]`, checking k.
fn rows<const K: usize>(array: &PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<Vec<[f64; K]>> {
    let view = array.as_array();
    if view.ncols() != K {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (n, {K}), not {:?}",
            view.shape()
        )));
    }
    Ok(view
        .rows()
        .into_iter()
        .map(|row| std::array::from_fn(|k| row[k]))
        .collect())
}

/// The rows of an `eval` call from its five (n, k) columns, read in place, or an error naming
/// the column of the wrong shape or length.
fn eval_rows(
    wi: &PyReadonlyArray2<'_, f64>,
    wo: &PyReadonlyArray2<'_, f64>,
    uv: &PyReadonlyArray2<'_, f64>,
    duv_dx: &PyReadonlyArray2<'_, f64>,
    duv_dy: &PyReadonlyArray2<'_, f64>,
) -> PyResult<Vec<EvalRow>> {
    let columns = [
        (wi.as_array(), "wi", 3),
        (wo.as_array(), "wo", 3),
        (uv.as_array(), "uv", 2),
        (duv_dx.as_array(), "duv_dx", 2),
        (duv_dy.as_array(), "duv_dy", 2),
    ];
    for (view, name, k) in &columns {
        if view.ncols() != *k {
            return Err(PyValueError::new_err(format!(
                "{name} must have shape (n, {k}), not {:?}",
                view.shape()
            )));
        }
    }
    let n = columns[0].0.nrows();
    same_length(
        n,
        &columns[1..]
            .iter()
            .map(|(view, name, _)| (view.nrows(), *name))
            .collect::<Vec<_>>(),
    )?;
    let [wi, wo, uv, dx, dy] = columns.map(|(view, _, _)| view);
    Ok((0..n)
        .map(|i| EvalRow {
            wi: [wi[[i, 0]], wi[[i, 1]], wi[[i, 2]]],
            wo: [wo[[i, 0]], wo[[i, 1]], wo[[i, 2]]],
            uv: [uv[[i, 0]], uv[[i, 1]]],
            duv_dx: [dx[[i, 0]], dx[[i, 1]]],
            duv_dy: [dy[[i, 0]], dy[[i, 1]]],
        })
        .collect())
}

/// A map's texels from a NumPy array of shape (H, W) or (H, W, channels), row 0 at the top.
fn map_spec<D: numpy::ndarray::Dimension>(view: numpy::ndarray::ArrayView<'_, f64, D>) -> MapSpec {
    let shape = view.shape();
    MapSpec {
        width: shape[1],
        height: shape[0],
        values: view.iter().copied().collect(),
    }
}

fn same_length(n: usize, others: &[(usize, &str)]) -> PyResult<()> {
    for (len, name) in others {
        if *len != n {
            return Err(PyValueError::new_err(format!(
                "{name} has {len} rows where wi has {n}"
            )));
        }
    }
    Ok(())
}

/// glint-eval's worker pool of this process ([`glint_eval::batch::process_pool`], rebuilt in a
/// forked child).
///
/// Called with the GIL held: `os.fork` holds the GIL too, so no other thread of this module
/// is inside the pool's lock when a process forks.
fn process_pool() -> PyResult<Arc<rayon::ThreadPool>> {
    glint_eval::batch::process_pool().map_err(pyo3::exceptions::PyRuntimeError::new_err)
}

/// Batches of at most this many rows are answered on the calling thread's pool directly;
/// larger ones are watched for Ctrl-C ([`answer_rows`]). A query's work is bounded by its node
/// budget, so a small batch ends soon whatever it holds.
const ROWS_ANSWERED_UNWATCHED: usize = 16;

/// How often a watched batch runs Python's signal handlers.
const SIGNAL_CHECK_INTERVAL: Duration = Duration::from_millis(50);

/// Answers every row in parallel on `pool` with glint-eval's batch machinery
/// ([`glint_eval::batch::answer_rows`]: each worker's scratch kept across calls, rows
/// dispatched in the order of `key`, answers in input order), with the GIL released.
///
/// A large batch runs on a scoped thread while the calling thread waits for it and, every
/// [`SIGNAL_CHECK_INTERVAL`], takes the GIL to run Python's signal handlers: Ctrl-C sets a flag
/// the workers read before each row, so the batch stops within about one query's time and the
/// `KeyboardInterrupt` is raised. A batch that ends returns at once (no polling delay).
fn answer_rows<I: Sync, O: Send>(
    py: Python<'_>,
    pool: &rayon::ThreadPool,
    inputs: &[I],
    key: impl Fn(&I) -> u64 + Sync + Send,
    answer: impl Fn(&mut QueryScratch, &I) -> O + Sync + Send,
) -> PyResult<Vec<O>> {
    let cancelled = AtomicBool::new(false);
    let work =
        || pool.install(|| glint_eval::batch::answer_rows(inputs, &key, &cancelled, &answer));
    let answers = if inputs.len() <= ROWS_ANSWERED_UNWATCHED {
        py.detach(work)
    } else {
        run_watched(py, &cancelled, work)?
    };
    // Every row is answered unless the batch was cancelled, which returned above.
    Ok(answers
        .into_iter()
        .map(|a| a.expect("answered: the batch was not cancelled"))
        .collect())
}

/// Runs `work` with the GIL released on a scoped thread while the calling thread waits for it
/// and, every [`SIGNAL_CHECK_INTERVAL`], takes the GIL to run Python's signal handlers. When
/// one raises (Ctrl-C: `KeyboardInterrupt`), `cancelled` is set, `work` is awaited (it reads
/// the flag and stops soon) and the exception is returned. Work that ends returns at once.
fn run_watched<T: Send>(
    py: Python<'_>,
    cancelled: &AtomicBool,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    let mut interrupt = None;
    let answers = py.detach(|| {
        std::thread::scope(|scope| {
            let (done, finished) = mpsc::channel();
            let worker = scope.spawn(move || {
                let answers = work();
                let _ = done.send(());
                answers
            });
            while let Err(RecvTimeoutError::Timeout) = finished.recv_timeout(SIGNAL_CHECK_INTERVAL)
            {
                if let Err(error) = Python::attach(|py| py.check_signals()) {
                    interrupt = Some(error);
                    cancelled.store(true, Ordering::Relaxed);
                    break;
                }
            }
            worker
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        })
    });
    match interrupt {
        Some(error) => Err(error),
        None => Ok(answers),
    }
}

/// The columns of n answers of K numbers each (NaN where a row failed) as a dict of flat
/// float64 arrays named `names`, plus the failed rows: `error_rows` (their indices, int64) and
/// `error_messages` (their messages, a list). The package makes the `error` column of them
/// (one string object per failed row, not per row).
fn columns<'py, const K: usize>(
    py: Python<'py>,
    names: [&str; K],
    answers: Vec<Result<[f64; K], String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (k, name) in names.iter().enumerate() {
        let column: Vec<f64> = answers
            .iter()
            .map(|a| a.as_ref().map_or(f64::NAN, |row| row[k]))
            .collect();
        dict.set_item(*name, PyArray1::from_vec(py, column))?;
    }
    let (rows, messages): (Vec<i64>, Vec<String>) = answers
        .into_iter()
        .enumerate()
        .filter_map(|(i, a)| a.err().map(|message| (i as i64, message)))
        .unzip();
    dict.set_item("error_rows", PyArray1::from_vec(py, rows))?;
    dict.set_item("error_messages", messages)?;
    Ok(dict)
}

#[pymethods]
impl Material {
    /// Builds a material from its `docs/eval.md` JSON object and its maps: density and
    /// roughness of shape (H, W), tint (H, W, 3), row 0 at the top of the texture.
    #[new]
    #[pyo3(signature = (material_json, density_map=None, alpha_map=None, tint_map=None))]
    fn new(
        material_json: &str,
        density_map: Option<PyReadonlyArray2<'_, f64>>,
        alpha_map: Option<PyReadonlyArray2<'_, f64>>,
        tint_map: Option<PyReadonlyArray3<'_, f64>>,
    ) -> PyResult<Self> {
        let value: serde_json::Value = serde_json::from_str(material_json)
            .map_err(|e| PyValueError::new_err(format!("invalid material JSON: {e}")))?;
        let mut spec = MaterialSpec::from_json(&value).map_err(PyValueError::new_err)?;
        spec.maps.density_map = density_map.map(|m| map_spec(m.as_array()));
        spec.maps.alpha_map = alpha_map.map(|m| map_spec(m.as_array()));
        if let Some(tint) = &tint_map
            && tint.shape()[2] != 3
        {
            return Err(PyValueError::new_err(format!(
                "tint_map must have shape (H, W, 3), not {:?}",
                tint.shape()
            )));
        }
        spec.maps.tint_map = tint_map.map(|m| map_spec(m.as_array()));
        let inner = spec.build().map_err(PyValueError::new_err)?;
        Ok(Self { inner })
    }

    /// The negligible-query test's constants (glint-brdf's `NegligibleTestConstants`) as a
    /// dict, for a material of one roughness level without a density map whose test is on;
    /// else None.
    #[getter]
    fn negligible_test<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(c) = self.inner.brdf().negligible_test() else {
            return Ok(None);
        };
        let dict = PyDict::new(py);
        dict.set_item("particles", c.particles)?;
        dict.set_item("threshold", c.threshold)?;
        dict.set_item("law_excess_ratio", c.law_excess_ratio)?;
        dict.set_item("unbounded_mass", c.unbounded_mass)?;
        dict.set_item("widening_arc", c.widening_arc)?;
        Ok(Some(dict))
    }

    /// The table Λ is read from (glint-brdf's `SmithTable`) as a dict, for a distribution that
    /// tabulates Λ (Ashikhmin–Shirley); else None. The Dr.Jit lobe interpolates it.
    #[getter]
    fn smith_table<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(table) = self.inner.brdf().parameters().distribution.smith_table() else {
            return Ok(None);
        };
        let dict = PyDict::new(py);
        dict.set_item("alpha", table.alpha())?;
        dict.set_item("u_nodes", table.u_nodes())?;
        dict.set_item("azimuth_nodes", table.azimuth_nodes())?;
        dict.set_item("values", table.values().to_vec())?;
        Ok(Some(dict))
    }

    /// The heap memory the material's maps hold, in bytes (glint-brdf's
    /// `DiscreteBrdf::map_bytes`).
    #[getter]
    fn map_bytes(&self) -> u64 {
        self.inner.brdf().map_bytes()
    }

    /// Whether f_hat, f_smooth and weights are one number per row.
    #[getter]
    fn gray(&self) -> bool {
        self.inner.is_gray()
    }

    /// The `eval` op over n rows: flat columns `count`, `expected_count`, `d_hat`, `f_hat_r`,
    /// `f_hat_g`, `f_hat_b`, `f_smooth_r`, …, `nodes_visited`, `negligible_bound` (NaN where the
    /// query was traversed) and `error`.
    /// With `expected_count` false the expected count's own traversal is skipped (NaN); with
    /// `f_smooth` false the smooth BRDF is not computed (NaN).
    #[pyo3(signature = (wi, wo, uv, duv_dx, duv_dy, expected_count = true, f_smooth = true))]
    #[allow(clippy::too_many_arguments)]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wo: PyReadonlyArray2<'py, f64>,
        uv: PyReadonlyArray2<'py, f64>,
        duv_dx: PyReadonlyArray2<'py, f64>,
        duv_dy: PyReadonlyArray2<'py, f64>,
        expected_count: bool,
        f_smooth: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let rows = eval_rows(&wi, &wo, &uv, &duv_dx, &duv_dy)?;
        let material = &self.inner;
        let pool = process_pool()?;
        let wanted = EvalColumns {
            expected_count,
            f_smooth,
        };
        let answers = answer_rows(py, &pool, &rows, EvalRow::locality_key, |scratch, row| {
            material.eval_row(scratch, row, wanted).map(|e| {
                [
                    e.count,
                    e.expected_count,
                    e.d_hat,
                    e.f_hat.x,
                    e.f_hat.y,
                    e.f_hat.z,
                    e.f_smooth.x,
                    e.f_smooth.y,
                    e.f_smooth.z,
                    f64::from(e.nodes_visited),
                    e.negligible_bound.unwrap_or(f64::NAN),
                ]
            })
        })?;
        columns(
            py,
            [
                "count",
                "expected_count",
                "d_hat",
                "f_hat_r",
                "f_hat_g",
                "f_hat_b",
                "f_smooth_r",
                "f_smooth_g",
                "f_smooth_b",
                "nodes_visited",
                "negligible_bound",
            ],
            answers,
        )
    }

    /// f̂ alone over n rows, as `eval` computes it (without its statistics): (n,) when F is
    /// grey, else (n, 3); NaN on the rows `eval` refuses (its `error` column names why). What a
    /// renderer shading pixel footprints asks for, at the lowest cost per row.
    fn f_hat<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wo: PyReadonlyArray2<'py, f64>,
        uv: PyReadonlyArray2<'py, f64>,
        duv_dx: PyReadonlyArray2<'py, f64>,
        duv_dy: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rows = eval_rows(&wi, &wo, &uv, &duv_dx, &duv_dy)?;
        let material = &self.inner;
        let pool = process_pool()?;
        let answers = answer_rows(py, &pool, &rows, EvalRow::locality_key, |scratch, row| {
            material
                .eval_row(scratch, row, EvalColumns::F_HAT)
                .map_or(DVec3::NAN, |e| e.f_hat)
        })?;
        if material.is_gray() {
            let column: Vec<f64> = answers.iter().map(|f| f.x).collect();
            return Ok(PyArray1::from_vec(py, column).into_any());
        }
        let flat: Vec<f64> = answers.iter().flat_map(|f| f.to_array()).collect();
        Ok(PyArray1::from_vec(py, flat)
            .reshape([answers.len(), 3])?
            .into_any())
    }

    /// The `sample` op over n rows of 3 or 4 uniform numbers: flat columns `wo_x`, `wo_y`,
    /// `wo_z` (NaN where no direction is sampled), `pdf`, `weight_r`, `weight_g`, `weight_b`
    /// (0 where no direction is sampled) and `error`. With `uv` (n, 2), a material with maps
    /// samples at those texture positions.
    #[pyo3(signature = (wi, u, uv=None))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        u: PyReadonlyArray2<'py, f64>,
        uv: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let wi = rows::<3>(&wi, "wi")?;
        let uv = uv.map(|uv| rows::<2>(&uv, "uv")).transpose()?;
        if let Some(uv) = &uv {
            same_length(wi.len(), &[(uv.len(), "uv")])?;
        }
        let u: Vec<Result<[f64; 4], String>> = match u.as_array().ncols() {
            3 => rows::<3>(&u, "u")?
                .into_iter()
                .map(uniforms_from_three)
                .collect(),
            _ => rows::<4>(&u, "u")
                .map_err(|_| {
                    PyValueError::new_err(format!(
                        "u must have shape (n, 4), or (n, 3) in the original form, not {:?}",
                        u.as_array().shape()
                    ))
                })?
                .into_iter()
                .map(Ok)
                .collect(),
        };
        same_length(wi.len(), &[(u.len(), "u")])?;
        let indices: Vec<usize> = (0..wi.len()).collect();
        let material = &self.inner;
        let pool = process_pool()?;
        let answers = answer_rows(
            py,
            &pool,
            &indices,
            |_| 0,
            |_, &i| {
                let u = u[i].clone()?;
                Ok(
                    match material.sample(wi[i], u, uv.as_ref().map(|uv| uv[i]))? {
                        Some(s) => [
                            s.wo.x, s.wo.y, s.wo.z, s.pdf, s.weight.x, s.weight.y, s.weight.z,
                        ],
                        None => [f64::NAN, f64::NAN, f64::NAN, 0.0, 0.0, 0.0, 0.0],
                    },
                )
            },
        )?;
        columns(
            py,
            [
                "wo_x", "wo_y", "wo_z", "pdf", "weight_r", "weight_g", "weight_b",
            ],
            answers,
        )
    }

    /// The `pdf` op over n rows: columns `pdf` and `error` (at texture positions `uv`, (n, 2),
    /// when given).
    #[pyo3(signature = (wi, wo, uv=None))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wo: PyReadonlyArray2<'py, f64>,
        uv: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (wi, wo) = (rows::<3>(&wi, "wi")?, rows::<3>(&wo, "wo")?);
        same_length(wi.len(), &[(wo.len(), "wo")])?;
        let uv = uv.map(|uv| rows::<2>(&uv, "uv")).transpose()?;
        if let Some(uv) = &uv {
            same_length(wi.len(), &[(uv.len(), "uv")])?;
        }
        let indices: Vec<usize> = (0..wi.len()).collect();
        let material = &self.inner;
        let pool = process_pool()?;
        let answers = answer_rows(
            py,
            &pool,
            &indices,
            |_| 0,
            |_, &i| {
                material
                    .pdf(wi[i], wo[i], uv.as_ref().map(|uv| uv[i]))
                    .map(|p| [p])
            },
        )?;
        columns(py, ["pdf"], answers)
    }
}

/// The native part of the Python package `glint`.
#[pymodule]
fn _glint(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<Material>()?;
    render::register(module)?;
    module.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The names of glint-brdf's table of kinds, in its order.
    let distributions: Vec<&str> = DistributionKind::ALL
        .iter()
        .map(|kind| kind.name())
        .collect();
    module.add("DISTRIBUTIONS", PyTuple::new(module.py(), distributions)?)?;
    // The most worker threads of any pool (glint_eval::batch::MAX_THREADS).
    module.add("MAX_THREADS", glint_eval::batch::MAX_THREADS)?;
    Ok(())
}
