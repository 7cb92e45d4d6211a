//! # icrflow for Python
//!
//! The PyO3 module `icrflow`: a thin skin over `icrflow-grasp` (objects, alpha*, epsilon,
//! force closure, ICRs) and `icrflow-plan` (the offline rolling planner, through the configs
//! of `icrflow-scenario`). No IPC: nothing of the pipeline's processes is here. Arrays come
//! in as numpy arrays (float64 read in place, whatever their strides; other dtypes converted
//! once) and go out as numpy arrays that own the vectors Rust computed (no copy). Batches
//! release the GIL and run on every core. The API reference is `python/README.md` and the
//! stubs `python/icrflow.pyi`.

#![warn(missing_docs)]

mod convert;
mod object;
mod plan;
mod problem;

use pyo3::prelude::*;

pyo3::create_exception!(
    icrflow,
    IcrflowError,
    pyo3::exceptions::PyException,
    "A grasp or plan that cannot be computed (not force closure for ICRs, a margin above the grasp's alpha*, a scenario the planner refuses), with the message the icrflow CLI prints."
);

/// icrflow: exact grasp quality alpha*, 6D independent contact regions and an in-hand
/// rolling planner.
///
/// - `Object`: a closed mesh (`Object.sphere`, `.ellipsoid`, `.mesh(path)`,
///   `.from_arrays(vertices, faces)`).
/// - `GraspProblem(obj, friction, cone_edges=8, space="spatial", rho=None)`:
///   `.evaluate(contacts)`, `.icrs(contacts, alpha)`, `.evaluate_batch(contacts)`.
/// - `plan(config)`: the offline rolling plan of a scenario (a TOML path or a dict).
/// - `IcrflowError`: what cannot be computed, with the CLI's message; bad input raises
///   `ValueError`.
#[pymodule]
fn icrflow(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("IcrflowError", m.py().get_type::<IcrflowError>())?;
    m.add_class::<object::Object>()?;
    m.add_class::<problem::GraspProblem>()?;
    m.add_class::<problem::Evaluation>()?;
    m.add_class::<problem::Region>()?;
    m.add_class::<plan::Plan>()?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    Ok(())
}
