//! Analysis on numpy arrays: NUFFT types 1 and 2, the velocity autocorrelation, norms, the mean
//! squared displacement, the Bingham closure and the relative entropy. Every array is checked
//! here too (shapes, finite values, ranges): errors, never panics.

use crate::{Radial, runtime_error, value_error};
use motile_analysis::correlation::{CorrelationOptions, sampled_vector_coefficients};
use motile_analysis::nufft::NufftPlan;
use num_complex::Complex64;
use numpy::ndarray::{Array1, Array2, Array3, Array4};
use numpy::{IntoPyArray, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// An error naming `name` if a value is NaN or infinite (`width` values per row, for the row's
/// index in the message).
fn check_finite(name: &str, values: &[f64], width: usize) -> PyResult<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(value_error(format!(
            "{name}: row {} holds {} (values must be finite)",
            i / width.max(1),
            values[i]
        ))),
    }
}

/// Complex values as interleaved reals, for [`check_finite`].
fn complex_parts(values: &[Complex64]) -> Vec<f64> {
    values.iter().flat_map(|c| [c.re, c.im]).collect()
}

/// An error unless `box_length` is positive and finite.
fn check_box(box_length: f64) -> PyResult<()> {
    if box_length > 0.0 && box_length.is_finite() {
        Ok(())
    } else {
        Err(value_error(format!(
            "box_length: expected a positive finite length, got {box_length}"
        )))
    }
}

/// An error unless the mode counts fit in memory (at most 4096 per axis, 2^30 in all).
fn check_modes(modes: [usize; 3]) -> PyResult<()> {
    let total = modes.iter().try_fold(1usize, |a, &m| a.checked_mul(m));
    if modes.iter().all(|&m| (1..=4096).contains(&m)) && total.is_some_and(|t| t <= 1 << 30) {
        Ok(())
    } else {
        Err(value_error(format!(
            "modes: expected 1 to 4096 per axis and at most 2^30 in all, got {modes:?}"
        )))
    }
}

/// Points `(N, 3)` as rows.
fn points3(a: &PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<Vec<[f64; 3]>> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(value_error(format!(
            "{name}: expected shape (N, 3), got {shape:?}"
        )));
    }
    let s = a.as_slice().map_err(value_error)?;
    check_finite(name, s, 3)?;
    Ok(s.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Type-1 NUFFT: `c(m) = sum_j s_j exp(-i k_m . x_j)`, `k_m = 2 pi m / L`, on `modes` per axis
/// (centred: `m` from `-M/2` to `M/2 - 1`); each row of `strengths` (`(K, N)`) a transform.
/// Returns `(K, M2, M1, M0)`, x fastest.
#[pyfunction]
pub(crate) fn nufft1<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    strengths: PyReadonlyArray2<'py, Complex64>,
    box_length: f64,
    modes: [usize; 3],
    tolerance: f64,
) -> PyResult<Bound<'py, numpy::PyArray4<Complex64>>> {
    check_box(box_length)?;
    check_modes(modes)?;
    let x = points3(&points, "points")?;
    let [k, n] = [strengths.shape()[0], strengths.shape()[1]];
    if n != x.len() {
        return Err(value_error(format!(
            "strengths: expected shape (K, {}), got ({k}, {n})",
            x.len()
        )));
    }
    let s = strengths.as_slice().map_err(value_error)?.to_vec();
    check_finite("strengths", &complex_parts(&s), 2 * n)?;
    let out = py
        .detach(move || -> Result<Vec<Vec<Complex64>>, String> {
            let mut plan = NufftPlan::new(modes, tolerance).map_err(|e| e.to_string())?;
            plan.set_points(&x, box_length).map_err(|e| e.to_string())?;
            let rows: Vec<&[Complex64]> = s.chunks_exact(n.max(1)).collect();
            plan.type1(&rows[..k]).map_err(|e| e.to_string())
        })
        .map_err(value_error)?;
    let flat: Vec<Complex64> = out.into_iter().flatten().collect();
    Ok(
        Array4::from_shape_vec((k, modes[2], modes[1], modes[0]), flat)
            .map_err(value_error)?
            .into_pyarray(py),
    )
}

/// Type-2 NUFFT: `s_j = sum_m c(m) exp(+i k_m . x_j)` for coefficients `(K, M2, M1, M0)`
/// (x fastest, centred modes). Returns `(K, N)`.
#[pyfunction]
pub(crate) fn nufft2<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    coefficients: numpy::PyReadonlyArray4<'py, Complex64>,
    box_length: f64,
    tolerance: f64,
) -> PyResult<Bound<'py, numpy::PyArray2<Complex64>>> {
    check_box(box_length)?;
    let x = points3(&points, "points")?;
    let sh = coefficients.shape().to_vec();
    let (k, modes) = (sh[0], [sh[3], sh[2], sh[1]]);
    check_modes(modes)?;
    let c = coefficients.as_slice().map_err(value_error)?.to_vec();
    check_finite(
        "coefficients",
        &complex_parts(&c),
        2 * sh[1] * sh[2] * sh[3],
    )?;
    let n = x.len();
    let out = py
        .detach(move || -> Result<Vec<Vec<Complex64>>, String> {
            let mut plan = NufftPlan::new(modes, tolerance).map_err(|e| e.to_string())?;
            plan.set_points(&x, box_length).map_err(|e| e.to_string())?;
            let m = modes[0] * modes[1] * modes[2];
            let rows: Vec<&[Complex64]> = c.chunks_exact(m.max(1)).collect();
            plan.type2(&rows[..k]).map_err(|e| e.to_string())
        })
        .map_err(value_error)?;
    let flat: Vec<Complex64> = out.into_iter().flatten().collect();
    Ok(Array2::from_shape_vec((k, n), flat)
        .map_err(value_error)?
        .into_pyarray(py))
}

/// The radial autocorrelation of the velocity field sampled at `points` (`(N, 3)`, a periodic
/// box of side `box_length`) by `velocities` (`(N, 3)`): the point field
/// `(|V|/N) sum_n u_n delta(x - x_n)`, its Fourier coefficients on `modes` per axis by a type-1
/// NUFFT at `tolerance`, `Corr(r) = sum_k |u~(k)|^2 j0(|k| r)` at radii spaced `shell_width`
/// (docs/MODEL.md A2). Returns `(r, corr)`.
#[pyfunction]
#[pyo3(signature = (points, velocities, box_length, modes=None, tolerance=1e-6, shell_width=None))]
pub(crate) fn velocity_autocorrelation<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    velocities: PyReadonlyArray2<'py, f64>,
    box_length: f64,
    modes: Option<usize>,
    tolerance: f64,
    shell_width: Option<f64>,
) -> PyResult<Radial<'py>> {
    check_box(box_length)?;
    let opts = CorrelationOptions {
        modes,
        tolerance,
        ..CorrelationOptions::default()
    };
    let m = opts.modes_for(box_length);
    check_modes([m; 3])?;
    let x = points3(&points, "points")?;
    let u = points3(&velocities, "velocities")?;
    if u.len() != x.len() {
        return Err(value_error(format!(
            "velocities: expected shape ({}, 3), got ({}, 3)",
            x.len(),
            u.len()
        )));
    }
    if let Some(w) = shell_width
        && !(w > 0.0 && w.is_finite())
    {
        return Err(value_error(format!(
            "shell_width: expected a positive length, got {w}"
        )));
    }
    let (r, c) = py
        .detach(move || {
            sampled_vector_coefficients(&x, &u, box_length, &opts)
                .map(|spec| spec.correlation(shell_width))
        })
        .map(|corr| (corr.r, corr.value))
        .map_err(value_error)?;
    Ok((
        Array1::from(r).into_pyarray(py),
        Array1::from(c).into_pyarray(py),
    ))
}

/// The volume-averaged L2 norm `sqrt(<sum_c v_c^2>)` of a field given as components `(C, P)`
/// (each row one component's values at `P` grid points).
#[pyfunction]
pub(crate) fn l2_norm(field: PyReadonlyArray2<'_, f64>) -> PyResult<f64> {
    let [c, p] = [field.shape()[0], field.shape()[1]];
    let s = field.as_slice().map_err(value_error)?;
    check_finite("field", s, p)?;
    let rows: Vec<&[f64]> = s.chunks_exact(p.max(1)).take(c).collect();
    Ok(motile_analysis::stats::volume_l2_norm(&rows))
}

/// Mean squared displacement `<|x_t - x_0|^2>` of unwrapped positions `(N, 3)`.
#[pyfunction]
pub(crate) fn msd(x0: PyReadonlyArray2<'_, f64>, xt: PyReadonlyArray2<'_, f64>) -> PyResult<f64> {
    let a = points3(&x0, "x0")?;
    let b = points3(&xt, "xt")?;
    if a.len() != b.len() {
        return Err(value_error(format!(
            "xt: expected shape ({}, 3), got ({}, 3)",
            a.len(),
            b.len()
        )));
    }
    Ok(motile_analysis::stats::mean_squared_displacement(&a, &b))
}

/// The Bingham closure tables of `degree` (built once per process, cached on disk).
fn closure(degree: usize) -> PyResult<&'static motile_meanfield::closure::BinghamClosure> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static TABLES: OnceLock<
        Mutex<HashMap<usize, &'static motile_meanfield::closure::BinghamClosure>>,
    > = OnceLock::new();
    if !(10..=200).contains(&degree) {
        return Err(value_error(format!(
            "degree: expected 10 to 200 (a run's closure_degree), got {degree}"
        )));
    }
    let map = TABLES.get_or_init(|| Mutex::new(HashMap::new()));
    let mut map = map
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(t) = map.get(&degree) {
        return Ok(t);
    }
    let t = motile_experiments::run::meanfield::closure_tables(degree).map_err(runtime_error)?;
    let t: &'static _ = Box::leak(Box::new(t));
    map.insert(degree, t);
    Ok(t)
}

/// Q tensors as rows `(P, 6)` (components xx, xy, xz, yy, yz, zz) to the solver's six
/// component arrays.
fn q_components(q: &PyReadonlyArray2<'_, f64>) -> PyResult<[Vec<f64>; 6]> {
    let shape = q.shape();
    if shape[1] != 6 {
        return Err(value_error(format!(
            "q: expected shape (P, 6) (xx, xy, xz, yy, yz, zz), got {shape:?}"
        )));
    }
    let s = q.as_slice().map_err(value_error)?;
    check_finite("q", s, 6)?;
    for (p, row) in s.chunks_exact(6).enumerate() {
        let tr = row[0] + row[3] + row[5];
        if tr.is_nan() || tr <= 0.0 {
            return Err(value_error(format!(
                "q: row {p} has trace {tr}: a second moment needs a positive trace"
            )));
        }
    }
    Ok(std::array::from_fn(|c| {
        s.chunks_exact(6).map(|row| row[c]).collect()
    }))
}

/// The Bingham closure's fourth moment `c S_(ij)(kl)` of each Q (`(P, 6)` rows), as symmetric
/// `(P, 6, 6)` matrices over the components xx, xy, xz, yy, yz, zz (tables of `degree`).
#[pyfunction]
#[pyo3(signature = (q, degree=20))]
pub(crate) fn bingham_closure<'py>(
    py: Python<'py>,
    q: PyReadonlyArray2<'py, f64>,
    degree: usize,
) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
    let comps = q_components(&q)?;
    let tables = closure(degree)?;
    let field = py.detach(|| {
        motile_meanfield::solver::closure_field::ClosureField::new(tables, &comps, false)
    });
    let t = field.tensors();
    let mut out = vec![0.0; t.len() * 36];
    for (p, m) in t.iter().enumerate() {
        let mut k = 0;
        for a in 0..6 {
            for b in a..6 {
                out[p * 36 + a * 6 + b] = m[k];
                out[p * 36 + b * 6 + a] = m[k];
                k += 1;
            }
        }
    }
    Ok(Array3::from_shape_vec((t.len(), 6, 6), out)
        .map_err(value_error)?
        .into_pyarray(py))
}

/// The relative entropy `H = <c ln c + c h(Q/c)>` of a field of Q tensors (`(P, 6)` rows, each
/// a grid point of equal volume; `h` the Bingham distribution's entropy density from the tables
/// of `degree`), the volume average docs/MODEL.md §4 reports.
#[pyfunction]
#[pyo3(signature = (q, degree=20))]
pub(crate) fn relative_entropy(
    py: Python<'_>,
    q: PyReadonlyArray2<'_, f64>,
    degree: usize,
) -> PyResult<f64> {
    let comps = q_components(&q)?;
    let tables = closure(degree)?;
    let field = py.detach(|| {
        motile_meanfield::solver::closure_field::ClosureField::new(tables, &comps, true)
    });
    Ok(field.entropy)
}
