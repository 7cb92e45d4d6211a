//! Python values in and out: arrays checked for shape and finiteness (with errors naming the
//! argument and the element), error mapping, JSON values as Python objects.

use icrflow_grasp::math::{Real, Vec3};
use numpy::ndarray::{Array, ArrayViewD, Dimension, IxDyn};
use numpy::{
    IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::IcrflowError;

/// A `ValueError` with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// The package exception with `message`.
pub fn icrflow_error(message: impl Into<String>) -> PyErr {
    IcrflowError::new_err(message.into())
}

/// An I/O error as Python's: `FileNotFoundError` for a missing file, else `OSError`.
pub fn io_error(kind: std::io::ErrorKind, message: String) -> PyErr {
    if kind == std::io::ErrorKind::NotFound {
        PyFileNotFoundError::new_err(message)
    } else {
        PyOSError::new_err(message)
    }
}

/// `obj` as a numpy array (itself when it is one, else `numpy.asarray(obj)`).
fn as_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        return Ok(a.clone());
    }
    let np = obj.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (obj,))
        .map_err(|e| value_error(format!("{name}: not an array of numbers ({e})")))?;
    Ok(a.cast_into::<PyUntypedArray>()?)
}

/// The numbers of an array argument, by kind.
pub enum Numbers<'py> {
    /// Floating point, as float64 (read in place when the array is float64).
    Real(PyReadonlyArrayDyn<'py, f64>),
    /// Integers (as int64).
    Integer(PyReadonlyArrayDyn<'py, i64>),
}

/// Reads an array argument of numbers: float64 in place (any strides), other floats and
/// integers converted; anything else (bool, objects, strings, ragged lists) is a
/// `ValueError` naming `name`.
pub fn numbers<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Numbers<'py>> {
    let a = as_array(obj, name)?;
    let kind = a.dtype().kind();
    match kind {
        b'f' => {
            let a = if a.dtype().is_equiv_to(&numpy::dtype::<f64>(obj.py())) {
                a.into_any()
            } else {
                a.call_method1("astype", ("float64",))?
            };
            Ok(Numbers::Real(a.extract()?))
        }
        b'i' | b'u' => {
            let a = if a.dtype().is_equiv_to(&numpy::dtype::<i64>(obj.py())) {
                a.into_any()
            } else {
                if kind == b'u' {
                    let np = obj.py().import("numpy")?;
                    let big: bool = np
                        .call_method1("any", (a.call_method1("__gt__", (i64::MAX as u64,))?,))?
                        .extract()?;
                    if big {
                        return Err(value_error(format!("{name}: an index is too large")));
                    }
                }
                a.call_method1("astype", ("int64",))?
            };
            Ok(Numbers::Integer(a.extract()?))
        }
        _ => Err(value_error(format!(
            "{name}: expected numbers, got an array of dtype {}",
            a.dtype()
        ))),
    }
}

/// Reads a float array of shape `(..., 3)`-style `shape` (`None`: any length on that axis),
/// checking every element is finite; the errors name `name` and the element.
pub fn real_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    shape: &[Option<usize>],
    what: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let a = match numbers(obj, name)? {
        Numbers::Real(a) => a,
        Numbers::Integer(a) => a.as_any().call_method1("astype", ("float64",))?.extract()?,
    };
    check_shape(name, a.shape(), shape, what)?;
    check_finite(name, &a.as_array())?;
    Ok(a)
}

/// Checks `got` against `want` (`None`: any length).
pub fn check_shape(name: &str, got: &[usize], want: &[Option<usize>], what: &str) -> PyResult<()> {
    let ok =
        got.len() == want.len() && got.iter().zip(want).all(|(g, w)| w.is_none_or(|w| *g == w));
    if ok {
        Ok(())
    } else {
        Err(value_error(format!(
            "{name}: expected {what}, got an array of shape {}",
            shape_str(got)
        )))
    }
}

/// `(2, 3)` for a shape.
pub fn shape_str(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The first non-finite element, named by its index.
pub fn check_finite(name: &str, a: &ArrayViewD<'_, f64>) -> PyResult<()> {
    match a.indexed_iter().find(|(_, x)| !x.is_finite()) {
        None => Ok(()),
        Some((index, x)) => Err(value_error(format!(
            "{name}{}: must be finite, got {x}",
            index_str(index.slice())
        ))),
    }
}

/// `[1, 2]` for an index.
pub fn index_str(index: &[usize]) -> String {
    format!(
        "[{}]",
        index
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// Row `i` of an `(n, 3)` view as a point.
pub fn point(a: &ArrayViewD<'_, f64>, index: &[usize]) -> Vec3 {
    let mut at = index.to_vec();
    let axis = at.len();
    at.push(0);
    let x = a[IxDyn(&at)];
    at[axis] = 1;
    let y = a[IxDyn(&at)];
    at[axis] = 2;
    Vec3::new(x, y, a[IxDyn(&at)])
}

/// Points as an `(n, 3)` array.
pub fn points_out<'py>(
    py: Python<'py>,
    points: impl ExactSizeIterator<Item = Vec3>,
) -> Bound<'py, PyArrayDyn<f64>> {
    let n = points.len();
    let mut flat = Vec::with_capacity(3 * n);
    for p in points {
        flat.extend_from_slice(&[p.x, p.y, p.z]);
    }
    array_out(py, flat, &[n, 3])
}

/// A flat vector as an array of `shape` (the vector becomes the array's buffer: no copy).
pub fn array_out<'py, T: numpy::Element>(
    py: Python<'py>,
    flat: Vec<T>,
    shape: &[usize],
) -> Bound<'py, PyArrayDyn<T>> {
    #[expect(
        clippy::expect_used,
        reason = "every caller builds `flat` with the shape's size"
    )]
    let a = Array::from_shape_vec(IxDyn(shape), flat)
        .expect("callers pass a vector of the shape's size");
    a.into_pyarray(py)
}

/// A JSON value as a Python object (dicts, lists, numbers, strings, None).
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::IntoPyObjectExt;
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_bound_py_any(py)?,
        Value::Number(n) => match (n.as_u64(), n.as_i64(), n.as_f64()) {
            (Some(u), _, _) => u.into_bound_py_any(py)?,
            (None, Some(i), _) => i.into_bound_py_any(py)?,
            (None, None, Some(f)) => f.into_bound_py_any(py)?,
            _ => Real::NAN.into_bound_py_any(py)?,
        },
        Value::String(s) => s.into_bound_py_any(py)?,
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// A path argument: `str` or `os.PathLike`.
pub fn path_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<std::path::PathBuf> {
    obj.extract::<std::path::PathBuf>().map_err(|_| {
        value_error(format!(
            "{name}: expected a path (str or os.PathLike), got {}",
            type_name(obj)
        ))
    })
}

/// The Python type name of `obj`.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "object".into())
}

/// The path shown for a config given as a dict (relative file names in it are relative to
/// the working directory).
pub fn dict_path() -> PyResult<std::path::PathBuf> {
    let cwd = std::env::current_dir()
        .map_err(|e| io_error(e.kind(), format!("cannot read the working directory: {e}")))?;
    Ok(cwd.join("<dict>"))
}
