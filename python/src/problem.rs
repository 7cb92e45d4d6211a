//! `icrflow.GraspProblem`: alpha*, epsilon and force closure of grasps, one or a batch on
//! every core, and their independent contact regions.

use icrflow_grasp::icr::IcrError;
use icrflow_grasp::math::Real;
use icrflow_grasp::quality::{
    Closure, Evaluation as Graded, EvaluationScratch, GraspProblem as Problem,
};
use icrflow_grasp::wrench::{ContactModel, Space, WrenchFrame};
use numpy::ndarray::{ArrayViewD, Axis, Dimension as _};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods as _};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{self, Numbers, array_out, icrflow_error, points_out, value_error};
use crate::object::{Object, chain};

/// Contacts as given: points to snap to the nearest candidates, or candidate indices.
enum Contacts<'py> {
    Points(PyReadonlyArrayDyn<'py, f64>),
    Indices(PyReadonlyArrayDyn<'py, i64>),
}

/// The same, as views that can cross into the threads of a batch.
#[derive(Clone, Copy)]
enum ContactsView<'a> {
    Points(&'a ArrayViewD<'a, f64>),
    Indices(&'a ArrayViewD<'a, i64>),
}

const SINGLE: &str =
    "an (n, 3) float array of contact points or an (n,) integer array of candidate indices";
const BATCH: &str =
    "an (N, n, 3) float array of contact points or an (N, n) integer array of candidate indices";

/// Candidate indices and distances.
type Snapped<'py> = (Bound<'py, PyArrayDyn<i64>>, Bound<'py, PyArrayDyn<f64>>);

/// A grasp evaluation problem: one object, one contact model.
///
/// `GraspProblem(obj, friction, cone_edges=8, space="spatial", rho=None)` computes once
/// what depends only on the object and the contact model: the object wrenches of every facet
/// (the object wrench space, OWS) and the primitive wrenches of every candidate contact
/// point, in the body frame. Then each grasp costs tens of microseconds.
///
/// - `friction`: the Coulomb coefficient mu (>= 0); `cone_edges`: edges of the linearised
///   friction cone (3 to 64).
/// - `space`: `"spatial"` (6D wrenches `[f; (p - c) x f / rho]`, candidates: the object's
///   facets) or `"planar"` (`(f_x, f_y, tau_z / rho)`, candidates: the object's section by
///   the plane through the centre of mass, as in the paper).
/// - `rho`: the torque normalisation length (m); default the object's largest radius.
///
/// Contacts are given either as points, an `(n, 3)` float array (each snapped to the nearest
/// candidate), or as candidate indices, an `(n,)` integer array (rows of `candidates`).
///
/// Methods: `evaluate(contacts)` (alpha*, epsilon, force closure, the hull),
/// `icrs(contacts, alpha)` (the independent contact regions with margin alpha),
/// `evaluate_batch(contacts)` (N grasps on every core, the GIL released), `snap(points)`.
#[pyclass(module = "icrflow", frozen)]
pub struct GraspProblem {
    problem: Problem,
    object: Py<Object>,
}

/// The result of `GraspProblem.evaluate`: one grasp's quality.
#[pyclass(module = "icrflow", frozen, get_all)]
pub struct Evaluation {
    /// alpha* (paper eq. 6): the largest scale of the object wrench space inside the grasp's
    /// wrench hull; 0 unless force closure.
    alpha_star: Real,
    /// The Ferrari-Canny epsilon (L1): positive exactly when force closure, 0 on the
    /// boundary, negative outside.
    epsilon: Real,
    /// Whether the grasp is force closure.
    force_closure: bool,
    /// `"force_closure"`, `"origin_on_boundary"`, `"origin_outside"` or `"degenerate"`.
    closure: String,
    /// The contacts' candidate indices, `(n,)`.
    contacts: Py<PyArrayDyn<i64>>,
    /// The contacts' candidate points, `(n, 3)` (m).
    points: Py<PyArrayDyn<f64>>,
    /// Distance from each given point to its candidate (m; 0 for indices), `(n,)`.
    snap_distances: Py<PyArrayDyn<f64>>,
    /// Number of facets of the grasp wrench hull (0 when degenerate).
    hull_facets: usize,
    /// Unit outward normals `a_f` of the hull's facets, `(hull_facets, dim)`.
    hull_normals: Py<PyArrayDyn<f64>>,
    /// Offsets `b_f` of the hull's facets (`a_f . w <= b_f`), `(hull_facets,)`.
    hull_offsets: Py<PyArrayDyn<f64>>,
    /// The facet attaining alpha*, when force closure.
    limiting_facet: Option<usize>,
}

#[pymethods]
impl Evaluation {
    fn __repr__(&self) -> String {
        format!(
            "Evaluation(alpha_star={}, epsilon={}, force_closure={}, closure={:?}, hull_facets={})",
            self.alpha_star,
            self.epsilon,
            if self.force_closure { "True" } else { "False" },
            self.closure,
            self.hull_facets
        )
    }
}

/// One contact's independent contact region: any choice of one point per region keeps the
/// grasp's quality >= alpha.
#[pyclass(module = "icrflow", frozen, get_all)]
pub struct Region {
    /// The contact's candidate index.
    contact: usize,
    /// Candidate indices in the region, ascending (the contact included), `(m,)`.
    indices: Py<PyArrayDyn<i64>>,
    /// Their candidate points, `(m, 3)` (m).
    points: Py<PyArrayDyn<f64>>,
    /// Search zones of the contact (its primitive wrenches that are hull vertices).
    zones: usize,
}

#[pymethods]
impl Region {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Region(contact={}, size={}, zones={})",
            self.contact,
            self.indices.bind(py).len(),
            self.zones
        )
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.indices.bind(py).len()
    }
}

fn closure_name(c: Closure) -> &'static str {
    match c {
        Closure::ForceClosure => "force_closure",
        Closure::OriginOnBoundary => "origin_on_boundary",
        Closure::OriginOutside => "origin_outside",
        Closure::Degenerate { .. } => "degenerate",
    }
}

impl GraspProblem {
    fn contacts<'py>(&self, obj: &Bound<'py, PyAny>, batch: bool) -> PyResult<Contacts<'py>> {
        let name = "contacts";
        let (what, point_shape, index_shape): (_, &[Option<usize>], &[Option<usize>]) = if batch {
            (BATCH, &[None, None, Some(3)], &[None, None])
        } else {
            (SINGLE, &[None, Some(3)], &[None])
        };
        let contacts = match convert::numbers(obj, name)? {
            Numbers::Real(a) => {
                convert::check_shape(name, a.shape(), point_shape, what)?;
                convert::check_finite(name, &a.as_array())?;
                Contacts::Points(a)
            }
            Numbers::Integer(a) => {
                convert::check_shape(name, a.shape(), index_shape, what)?;
                let count = self.problem.candidates().len();
                if let Some((at, &i)) = a
                    .as_array()
                    .indexed_iter()
                    .find(|(_, i)| **i < 0 || **i as u64 >= count as u64)
                {
                    return Err(value_error(format!(
                        "{name}{}: candidate {i} does not exist (the problem has {count} candidates, 0 to {})",
                        convert::index_str(at.slice()),
                        count - 1
                    )));
                }
                Contacts::Indices(a)
            }
        };
        let per_grasp = contacts_per_grasp(&contacts, batch);
        if per_grasp == 0 {
            return Err(value_error(format!(
                "{name}: a grasp needs at least one contact"
            )));
        }
        Ok(contacts)
    }
}

fn contacts_per_grasp(c: &Contacts<'_>, batch: bool) -> usize {
    let shape = match c {
        Contacts::Points(a) => a.shape(),
        Contacts::Indices(a) => a.shape(),
    };
    shape[usize::from(batch)]
}

/// Fills `out` with the candidate indices of grasp `row` (`None`: a single grasp), and
/// `distances` with the snap distances.
fn resolve(
    problem: &Problem,
    c: ContactsView<'_>,
    row: Option<usize>,
    out: &mut Vec<usize>,
    distances: &mut Vec<Real>,
) {
    out.clear();
    distances.clear();
    match c {
        ContactsView::Points(a) => {
            let grasp = match row {
                Some(r) => a.index_axis(Axis(0), r),
                None => a.view(),
            };
            for i in 0..grasp.shape()[0] {
                let p = convert::point(&grasp, &[i]);
                // Finite (checked) and the problem has candidates (checked at construction).
                let (q, d) = problem.nearest_candidate(&p).unwrap_or((0, Real::NAN));
                out.push(q);
                distances.push(d);
            }
        }
        ContactsView::Indices(a) => {
            let grasp = match row {
                Some(r) => a.index_axis(Axis(0), r),
                None => a.view(),
            };
            // Checked to be in range.
            out.extend(grasp.iter().map(|&i| i as usize));
            distances.resize(out.len(), 0.0);
        }
    }
}

impl GraspProblem {
    fn evaluate_contacts(
        &self,
        py: Python<'_>,
        contacts: &Bound<'_, PyAny>,
    ) -> PyResult<(Vec<usize>, Vec<Real>, Graded)> {
        let c = self.contacts(contacts, false)?;
        let (mut indices, mut distances) = (Vec::new(), Vec::new());
        let graded = match &c {
            Contacts::Points(a) => {
                let a = a.as_array();
                py.detach(|| {
                    resolve(
                        &self.problem,
                        ContactsView::Points(&a),
                        None,
                        &mut indices,
                        &mut distances,
                    );
                    self.problem.evaluate(&indices)
                })
            }
            Contacts::Indices(a) => {
                let a = a.as_array();
                resolve(
                    &self.problem,
                    ContactsView::Indices(&a),
                    None,
                    &mut indices,
                    &mut distances,
                );
                self.problem.evaluate(&indices)
            }
        }
        .map_err(|e| icrflow_error(chain(&e)))?;
        Ok((indices, distances, graded))
    }
}

#[pymethods]
impl GraspProblem {
    #[new]
    #[pyo3(signature = (obj, friction, cone_edges = 8, space = "spatial", rho = None))]
    fn new(
        py: Python<'_>,
        obj: Bound<'_, Object>,
        friction: Real,
        cone_edges: usize,
        space: &str,
        rho: Option<Real>,
    ) -> PyResult<Self> {
        let space = match space {
            "spatial" => Space::Spatial,
            "planar" => Space::Planar,
            other => {
                return Err(value_error(format!(
                    "space: {other:?} is not a wrench space; use \"spatial\" (6D) or \"planar\" (f_x, f_y, tau_z / rho)"
                )));
            }
        };
        let model = ContactModel::new(friction, cone_edges).map_err(|e| {
            let key = if !friction.is_finite() || friction < 0.0 {
                "friction"
            } else {
                "cone_edges"
            };
            value_error(format!("{key}: {e}"))
        })?;
        let object = &obj.get().inner;
        let rho = rho.unwrap_or_else(|| object.max_radius());
        let frame = WrenchFrame::new(object.centre_of_mass, rho, space)
            .map_err(|e| value_error(format!("rho: {e}")))?;
        let candidates = match space {
            Space::Planar => {
                if object.section.samples.is_empty() {
                    return Err(value_error(
                        "space: the hand's plane does not cut the object: no planar candidates",
                    ));
                }
                object.section.samples.clone()
            }
            Space::Spatial => object.facets.clone(),
        };
        let problem = py
            .detach(|| Problem::new(&object.facets, candidates, frame, model))
            .map_err(|e| icrflow_error(chain(&e)))?;
        Ok(Self {
            problem,
            object: obj.unbind(),
        })
    }

    /// The object.
    #[getter]
    fn object(&self, py: Python<'_>) -> Py<Object> {
        self.object.clone_ref(py)
    }

    /// `"spatial"` or `"planar"`.
    #[getter]
    fn space(&self) -> &'static str {
        self.problem.space().name()
    }

    /// The friction coefficient mu.
    #[getter]
    fn friction(&self) -> Real {
        self.problem.model().mu()
    }

    /// Edges of the linearised friction cone.
    #[getter]
    fn cone_edges(&self) -> usize {
        self.problem.model().edges()
    }

    /// The torque normalisation length (m).
    #[getter]
    fn rho(&self) -> Real {
        self.problem.frame().rho()
    }

    /// Dimension of the wrench space (6 spatial, 3 planar).
    #[getter]
    fn dim(&self) -> usize {
        self.problem.dim()
    }

    /// The candidate contact points, `(k, 3)` (m); a contact index is a row of this array.
    #[getter]
    fn candidates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.problem.candidates().points.iter().copied())
    }

    /// The candidates' outward unit normals, `(k, 3)`.
    #[getter]
    fn candidate_normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        points_out(py, self.problem.candidates().normals.iter().copied())
    }

    /// Snaps points, `(n, 3)`, to their nearest candidates: `(indices (n,), distances (n,))`.
    fn snap<'py>(&self, py: Python<'py>, points: &Bound<'py, PyAny>) -> PyResult<Snapped<'py>> {
        let p = convert::real_array(
            points,
            "points",
            &[None, Some(3)],
            "an array of shape (n, 3)",
        )?;
        let p = p.as_array();
        let (mut indices, mut distances) = (Vec::new(), Vec::new());
        py.detach(|| {
            resolve(
                &self.problem,
                ContactsView::Points(&p),
                None,
                &mut indices,
                &mut distances,
            )
        });
        let n = indices.len();
        Ok((
            array_out(py, indices.into_iter().map(|i| i as i64).collect(), &[n]),
            array_out(py, distances, &[n]),
        ))
    }

    /// Evaluates one grasp: `contacts` is an `(n, 3)` float array of points (snapped to the
    /// nearest candidates) or an `(n,)` integer array of candidate indices. Returns an
    /// `Evaluation` (alpha_star, epsilon, force_closure, closure, the hull's facets).
    fn evaluate(&self, py: Python<'_>, contacts: &Bound<'_, PyAny>) -> PyResult<Evaluation> {
        let (indices, distances, e) = self.evaluate_contacts(py, contacts)?;
        let n = indices.len();
        let cands = self.problem.candidates();
        let (hull_facets, normals, offsets) = match &e.hull {
            Some(h) => (h.facet_count(), h.normals().to_vec(), h.offsets().to_vec()),
            None => (0, Vec::new(), Vec::new()),
        };
        Ok(Evaluation {
            alpha_star: e.quality,
            epsilon: e.epsilon,
            force_closure: e.force_closure(),
            closure: closure_name(e.closure).to_owned(),
            points: points_out(py, indices.iter().map(|&i| cands.points[i])).unbind(),
            contacts: array_out(py, indices.iter().map(|&i| i as i64).collect(), &[n]).unbind(),
            snap_distances: array_out(py, distances, &[n]).unbind(),
            hull_facets,
            hull_normals: array_out(py, normals, &[hull_facets, self.problem.dim()]).unbind(),
            hull_offsets: array_out(py, offsets, &[hull_facets]).unbind(),
            limiting_facet: e.limiting_facet,
        })
    }

    /// The independent contact regions of the grasp `contacts` (as for `evaluate`) with
    /// margin `alpha` (0 <= alpha <= the grasp's alpha*): a list of `Region`, one per contact,
    /// in order. Raises `icrflow.IcrflowError` when the grasp is not force closure or alpha
    /// exceeds its alpha* (the message says which), `ValueError` for a bad alpha.
    fn icrs(
        &self,
        py: Python<'_>,
        contacts: &Bound<'_, PyAny>,
        alpha: Real,
    ) -> PyResult<Vec<Region>> {
        if !alpha.is_finite() || alpha < 0.0 {
            return Err(value_error(format!(
                "alpha: must be finite and >= 0, got {alpha}"
            )));
        }
        let (indices, _, e) = self.evaluate_contacts(py, contacts)?;
        let regions = py
            .detach(|| self.problem.icrs(&indices, &e, alpha))
            .map_err(|e| match e {
                IcrError::BadMargin { .. } => value_error(format!("alpha: {e}")),
                e => icrflow_error(e.to_string()),
            })?;
        let cands = self.problem.candidates();
        Ok(regions
            .into_iter()
            .map(|r| {
                let m = r.members.len();
                Region {
                    contact: r.contact,
                    points: points_out(py, r.members.iter().map(|&q| cands.points[q as usize]))
                        .unbind(),
                    indices: array_out(py, r.members.iter().map(|&q| i64::from(q)).collect(), &[m])
                        .unbind(),
                    zones: r.zones,
                }
            })
            .collect())
    }

    /// Evaluates N grasps of n contacts each: `contacts` is an `(N, n, 3)` float array of
    /// points or an `(N, n)` integer array of candidate indices. Runs on `threads` threads
    /// (default: every core) with the GIL released. Returns a dict of arrays of length N:
    /// `alpha_star`, `epsilon` (float64) and `force_closure` (bool), equal to evaluating the
    /// grasps one by one.
    #[pyo3(signature = (contacts, threads = None))]
    fn evaluate_batch<'py>(
        &self,
        py: Python<'py>,
        contacts: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.contacts(contacts, true)?;
        let threads = match threads {
            Some(0) => return Err(value_error("threads: must be at least 1")),
            Some(t) => t,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let (points, indices);
        let view = match &c {
            Contacts::Points(a) => {
                points = a.as_array();
                ContactsView::Points(&points)
            }
            Contacts::Indices(a) => {
                indices = a.as_array();
                ContactsView::Indices(&indices)
            }
        };
        let n = match &c {
            Contacts::Points(a) => a.shape()[0],
            Contacts::Indices(a) => a.shape()[0],
        };
        let mut alpha = vec![0.0; n];
        let mut epsilon = vec![0.0; n];
        let mut closure = vec![false; n];
        let failed = py.detach(|| {
            batch(
                &self.problem,
                view,
                threads,
                &mut alpha,
                &mut epsilon,
                &mut closure,
            )
        });
        if let Some((i, message)) = failed {
            return Err(icrflow_error(format!("grasp {i}: {message}")));
        }
        let out = PyDict::new(py);
        out.set_item("alpha_star", array_out(py, alpha, &[n]))?;
        out.set_item("epsilon", array_out(py, epsilon, &[n]))?;
        out.set_item("force_closure", array_out(py, closure, &[n]))?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "GraspProblem(space={:?}, friction={}, cone_edges={}, rho={}, candidates={})",
            self.problem.space().name(),
            self.problem.model().mu(),
            self.problem.model().edges(),
            self.problem.frame().rho(),
            self.problem.candidates().len()
        )
    }
}

/// Evaluates the grasps of `c` on `threads` threads, each a contiguous block of rows, into
/// the outputs; returns the first grasp that could not be evaluated and why.
fn batch(
    problem: &Problem,
    c: ContactsView<'_>,
    threads: usize,
    alpha: &mut [Real],
    epsilon: &mut [Real],
    closure: &mut [bool],
) -> Option<(usize, String)> {
    let n = alpha.len();
    if n == 0 {
        return None;
    }
    let chunk = n.div_ceil(threads.min(n));
    let run = |start: usize, alpha: &mut [Real], epsilon: &mut [Real], closure: &mut [bool]| {
        let mut e = Graded::default();
        let mut scratch = EvaluationScratch::default();
        let (mut indices, mut distances) = (Vec::new(), Vec::new());
        for k in 0..alpha.len() {
            resolve(problem, c, Some(start + k), &mut indices, &mut distances);
            if let Err(err) = problem.evaluate_in(&indices, &mut e, &mut scratch) {
                return Some((start + k, chain(&err)));
            }
            alpha[k] = e.quality;
            epsilon[k] = e.epsilon;
            closure[k] = e.force_closure();
        }
        None
    };
    std::thread::scope(|s| {
        let handles: Vec<_> = alpha
            .chunks_mut(chunk)
            .zip(epsilon.chunks_mut(chunk))
            .zip(closure.chunks_mut(chunk))
            .enumerate()
            .map(|(t, ((a, e), f))| {
                let run = &run;
                s.spawn(move || run(t * chunk, a, e, f))
            })
            .collect();
        handles
            .into_iter()
            .filter_map(|h| {
                h.join()
                    .unwrap_or_else(|_| Some((0, "a worker thread panicked".into())))
            })
            .min_by_key(|(i, _)| *i)
    })
}

// The problem is shared by the batch's threads.
const _: () = {
    const fn sync<T: Send + Sync>() {}
    sync::<Problem>();
};
