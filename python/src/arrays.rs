//! numpy in, numpy out: the core's `[Vec3]` as `(n, 3)` float64 arrays and back.
//!
//! Reading the state makes one copy, straight into the new array's memory (`from_owned_array`
//! hands numpy the Rust buffer): a view of the live state would change under its reader while a
//! step runs with the GIL released, and the integrators swap their buffers into the state, so a
//! view could end up looking at scratch memory. Writing reads the caller's array in place (any
//! strides) without an intermediate copy.

use jello_core::Vec3;
use numpy::ndarray::Array2;
use numpy::{PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// `values` as a new `(n, 3)` float64 array.
pub fn to_array<'py>(py: Python<'py>, values: &[Vec3]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = values.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
    let array = Array2::from_shape_vec((values.len(), 3), flat)
        .expect("three numbers per vector make an (n, 3) array");
    PyArray2::from_owned_array(py, array)
}

/// An `(n, 3)` array of finite numbers (anything `numpy.asarray` makes one of) as vectors;
/// `what` names it in errors.
pub fn from_array(value: &Bound<'_, PyAny>, n: usize, what: &str) -> PyResult<Vec<Vec3>> {
    let array = float_array(value, what)?;
    let shape = array.shape();
    if shape != [n, 3] {
        return Err(PyValueError::new_err(format!(
            "{what}: expected an array of shape ({n}, 3), found shape {shape:?}"
        )));
    }
    let view = array.as_array();
    let mut out = Vec::with_capacity(n);
    for (i, row) in view.outer_iter().enumerate() {
        let v = Vec3::new(row[0], row[1], row[2]);
        if !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "{what}: row {i} is not finite: [{}, {}, {}]",
                v.x, v.y, v.z
            )));
        }
        out.push(v);
    }
    Ok(out)
}

/// `value` as a 2-D float64 array: itself when it is one, else what `numpy.asarray(value,
/// dtype=float64)` makes of it.
fn float_array<'py>(value: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArray2<'py, f64>> {
    if let Ok(a) = value.extract::<PyReadonlyArray2<'py, f64>>() {
        return Ok(a);
    }
    let py = value.py();
    let numpy = py.import("numpy")?;
    let converted = numpy
        .call_method1("asarray", (value, "float64"))
        .map_err(|e| {
            PyValueError::new_err(format!(
                "{what}: expected an (n, 3) array of numbers: {}",
                e.value(py)
            ))
        })?;
    let ndim: usize = converted.getattr("ndim")?.extract()?;
    if ndim != 2 {
        let shape = converted.getattr("shape")?.str()?.to_string();
        return Err(PyValueError::new_err(format!(
            "{what}: expected a 2-D array of shape (n, 3), found shape {shape}"
        )));
    }
    converted.extract::<PyReadonlyArray2<'py, f64>>()
}

/// A sequence of three finite numbers (a tuple, a list, a numpy array), `what` naming it.
pub fn vec3(value: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    numbers::<3>(value, what)
}

/// A sequence of `N` finite numbers, `what` naming it.
pub fn numbers<const N: usize>(value: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; N]> {
    let items: Vec<f64> = value.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "{what}: expected {N} numbers, found {}",
            describe(value)
        ))
    })?;
    let out: [f64; N] = items.as_slice().try_into().map_err(|_| {
        PyValueError::new_err(format!(
            "{what}: expected {N} numbers, found {}",
            items.len()
        ))
    })?;
    if let Some(bad) = out.iter().find(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{what}: expected finite numbers, found {bad}"
        )));
    }
    Ok(out)
}

/// A short description of a Python value for an error message.
fn describe(value: &Bound<'_, PyAny>) -> String {
    value
        .repr()
        .map(|r| {
            let r = r.to_string();
            if r.chars().count() > 60 {
                format!("{}…", r.chars().take(60).collect::<String>())
            } else {
                r
            }
        })
        .unwrap_or_else(|_| "a value".into())
}
