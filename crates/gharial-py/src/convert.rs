//! numpy arrays in and out, and errors across the boundary.
//!
//! Every array argument goes through [`vector`] or [`matrix`]: any real array-like
//! (numpy arrays of float or integer dtype, lists, tuples) is accepted; other dtypes
//! (complex, bool, strings, objects) and wrong shapes are a `ValueError` naming the
//! argument.

use faer::{Mat, MatRef};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::create_exception!(
    _gharial,
    GharialError,
    pyo3::exceptions::PyValueError,
    "An error reported by gharial's Rust core (invalid model, dimension, option, ...)."
);

/// A core error as a Python `GharialError` with the same message.
pub fn err(e: gharial::Error) -> PyErr {
    GharialError::new_err(e.to_string())
}

/// A multibody error as a Python `GharialError` with the same message.
pub fn mb_err(e: gharial_multibody::Error) -> PyErr {
    GharialError::new_err(e.to_string())
}

/// `ValueError(msg)`.
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// The object as a C-contiguous float64 numpy array, refusing non-real dtypes.
fn real_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| value_error(format!("{what}: not an array of real numbers ({e})")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(value_error(format!("{what}: expected real numbers, got dtype {dtype}")));
    }
    np.call_method1("ascontiguousarray", (arr, "float64"))
}

/// A vector of real numbers (a 1-D array-like; `n`: the required length).
pub fn vector(obj: &Bound<'_, PyAny>, what: &str, n: Option<usize>) -> PyResult<Vec<f64>> {
    if let Some(v) = contiguous_f64(obj) {
        return check_len(v, what, n);
    }
    let arr = real_array(obj, what)?;
    let a = arr.cast::<PyArray1<f64>>().map_err(|_| {
        let ndim = arr.getattr("ndim").and_then(|d| d.extract::<usize>()).unwrap_or(0);
        value_error(format!("{what}: expected a 1-D array, got {ndim} dimensions"))
    })?;
    let v = a.try_readonly().map_err(|e| value_error(format!("{what}: {e}")))?;
    let v = v.as_slice().map_err(|e| value_error(format!("{what}: {e}")))?.to_vec();
    check_len(v, what, n)
}

/// The entries of a contiguous float64 1-D numpy array, copied without any conversion
/// (the fast path); `None` for anything else.
fn contiguous_f64(obj: &Bound<'_, PyAny>) -> Option<Vec<f64>> {
    obj.cast::<PyArray1<f64>>().ok()?.to_vec().ok()
}

fn check_len(v: Vec<f64>, what: &str, n: Option<usize>) -> PyResult<Vec<f64>> {
    match n {
        Some(n) if v.len() != n => Err(value_error(format!("{what}: expected {n} entries, got {}", v.len()))),
        _ => Ok(v),
    }
}

/// A matrix of real numbers (a 2-D array-like; `shape`: the required shape).
pub fn matrix(obj: &Bound<'_, PyAny>, what: &str, shape: Option<(usize, usize)>) -> PyResult<Mat<f64>> {
    let arr = real_array(obj, what)?;
    let a = arr.cast::<PyArray2<f64>>().map_err(|_| {
        let ndim = arr.getattr("ndim").and_then(|d| d.extract::<usize>()).unwrap_or(0);
        value_error(format!("{what}: expected a 2-D array, got {ndim} dimensions"))
    })?;
    let (r, c) = (a.shape()[0], a.shape()[1]);
    if let Some((er, ec)) = shape
        && (er, ec) != (r, c)
    {
        return Err(value_error(format!(
            "{what}: expected shape ({er}, {ec}), got ({r}, {c})"
        )));
    }
    let ro = a.try_readonly().map_err(|e| value_error(format!("{what}: {e}")))?;
    let s = ro.as_slice().map_err(|e| value_error(format!("{what}: {e}")))?;
    Ok(Mat::from_fn(r, c, |i, j| s[i * c + j]))
}

/// A list of vectors (a sequence of 1-D array-likes or a 2-D array, one row each).
pub fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vec<f64>>> {
    let mut out = Vec::new();
    vectors_into(obj, what, &mut out)?;
    Ok(out)
}

/// Reads a list of vectors into `out` as [`vectors`] does, reusing its buffers: a list
/// of the shape `out` already has is read without allocation. On error `out` holds a
/// partial read.
pub fn vectors_into(obj: &Bound<'_, PyAny>, what: &str, out: &mut Vec<Vec<f64>>) -> PyResult<()> {
    if let Ok(a) = obj.cast::<PyArray2<f64>>()
        && let Ok(ro) = a.try_readonly()
        && let Ok(s) = ro.as_slice()
    {
        let (r, c) = (a.shape()[0], a.shape()[1]);
        out.resize_with(r, Vec::new);
        for (i, v) in out.iter_mut().enumerate() {
            v.clear();
            v.extend_from_slice(&s[i * c..(i + 1) * c]);
        }
        return Ok(());
    }
    let items = obj
        .try_iter()
        .map_err(|_| value_error(format!("{what}: expected a sequence of vectors")))?;
    let mut n = 0;
    for (i, item) in items.enumerate() {
        let item = item?;
        if i == out.len() {
            out.push(Vec::new());
        }
        if let Ok(a) = item.cast::<PyArray1<f64>>()
            && let Ok(v) = a.to_vec()
        {
            out[i] = v;
        } else {
            out[i] = vector(&item, &format!("{what}[{i}]"), None)?;
        }
        n = i + 1;
    }
    out.truncate(n);
    Ok(())
}

/// A 1-D numpy array copied from `v`.
pub fn array1<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v)
}

/// A 2-D numpy array copied from `m`.
pub fn array2<'py>(py: Python<'py>, m: MatRef<'_, f64>) -> Bound<'py, PyArray2<f64>> {
    let a = PyArray2::zeros(py, [m.nrows(), m.ncols()], false);
    {
        let mut w = a.readwrite();
        let s = w.as_slice_mut().expect("a new array is contiguous");
        for i in 0..m.nrows() {
            for j in 0..m.ncols() {
                s[i * m.ncols() + j] = m[(i, j)];
            }
        }
    }
    a
}

/// A list of 1-D numpy arrays.
pub fn arrays1<'py>(py: Python<'py>, vs: &[Vec<f64>]) -> PyResult<Bound<'py, pyo3::types::PyList>> {
    pyo3::types::PyList::new(py, vs.iter().map(|v| array1(py, v)))
}
