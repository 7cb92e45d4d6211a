//! `icrflow.plan(config)`: the offline rolling plan of a scenario, as `icrflow plan` makes it.

use anyhow::Context as _;
use icrflow_grasp::math::Real;
use icrflow_plan::planner::Plan as Planned;
use icrflow_scenario::{Config, Setup};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use crate::convert::{self, array_out, icrflow_error, json_to_py, value_error};

/// A plan: the trajectory as arrays, the summary and the finger switches.
#[pyclass(module = "icrflow", frozen, get_all)]
pub struct Plan {
    /// The summary, as `icrflow plan --json` prints it: `completed`, `stop_reason`,
    /// `rotation_deg`, `goal_deg`, `switches`, `steps`, `rolling_steps`, `min_quality`,
    /// `alpha`, `max_rolling_residual`, the rendezvous region counts (and
    /// `chosen_from_candidates` with `region_erosion`), `min_link_clearance_mm`,
    /// `min_squeeze_reserve_mm`.
    summary: Py<PyDict>,
    /// The trajectory, one row per step (S steps, F fingers of the hand, in `fingers`
    /// order): `step` (S,), `phase` (S,) str (`start`, `rolling`, `attach`, `detach`),
    /// `rotation_deg` (S,), `quality` (S,) (alpha* of the grasp in force), `fingers` (F,),
    /// `contact` (S, F) candidate index or -1 for a free finger, `point` (S, F, 3) (body
    /// frame, m; NaN when free), `angle_deg`, `cap_angle_deg` (S, F) (NaN when free),
    /// `tip_rotation_deg` (S, F), `tip_centre` (S, F, 3) (m), `joints_deg` (S, F, J) (J the
    /// most joints of any finger; NaN beyond a finger's own).
    trajectory: Py<PyDict>,
    /// The finger switches, one dict per attach step (as in `trajectory.json`, plus its
    /// `step`): `released`, `attached`, `reason`, the regions `icr_region`, `lp_region`,
    /// `brute_force`, `chosen_from` (how many of it the rendezvous was chosen from),
    /// `rendezvous`, `rendezvous_angle_deg`, `room_steps`, `ahead_deg`.
    switches: Py<PyList>,
}

#[pymethods]
impl Plan {
    fn __repr__(&self, py: Python<'_>) -> String {
        let s = self.summary.bind(py);
        let get = |k: &str| {
            s.get_item(k)
                .ok()
                .flatten()
                .and_then(|v| v.repr().ok().map(|r| r.to_string()))
                .unwrap_or_default()
        };
        format!(
            "Plan(completed={}, rotation_deg={}, steps={}, switches={}, min_quality={})",
            get("completed"),
            get("rotation_deg"),
            get("steps"),
            get("switches"),
            get("min_quality")
        )
    }
}

/// A Python value of a config dict as TOML; `key` names it in errors (`config.grasp.alpha`).
fn to_toml(obj: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        let i: i64 = obj.extract().map_err(|_| {
            value_error(format!("{key}: the integer {obj} does not fit in 64 bits"))
        })?;
        return Ok(toml::Value::Integer(i));
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(obj.extract()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(obj.extract()?));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        return Ok(toml::Value::Table(to_table(d, key)?));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let items = obj
            .try_iter()?
            .enumerate()
            .map(|(i, item)| to_toml(&item?, &format!("{key}[{i}]")))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(toml::Value::Array(items));
    }
    // numpy scalars and arrays, os.PathLike.
    if obj.hasattr("tolist")? {
        return to_toml(&obj.call_method0("tolist")?, key);
    }
    if obj.hasattr("__fspath__")? {
        return to_toml(&obj.call_method0("__fspath__")?, key);
    }
    Err(value_error(format!(
        "{key}: a {} cannot be a config value (use bool, int, float, str, list or dict)",
        convert::type_name(obj)
    )))
}

/// A dict shaped like the config file as a TOML table; keys whose value is `None` are left
/// out (TOML has no null).
fn to_table(d: &Bound<'_, PyDict>, key: &str) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in d.iter() {
        let name: String = k.extract().map_err(|_| {
            value_error(format!(
                "{key}: the key {} is not a string",
                k.repr().map(|r| r.to_string()).unwrap_or_default()
            ))
        })?;
        if v.is_none() {
            continue;
        }
        let value = to_toml(&v, &format!("{key}.{name}"))?;
        table.insert(name, value);
    }
    Ok(table)
}

/// The config of `plan(config)`: a path (read like `icrflow plan PATH`) or a dict.
pub fn config_arg(config: &Bound<'_, PyAny>) -> PyResult<Config> {
    if let Ok(d) = config.cast::<PyDict>() {
        let table = to_table(d, "config")?;
        let path = convert::dict_path()?;
        return Config::from_table(table, &path)
            .map_err(|e| value_error(format!("invalid config (a dict): {e:#}")));
    }
    let path = convert::path_arg(config, "config").map_err(|_| {
        value_error(format!(
            "config: expected a path or a dict shaped like the TOML file, got {}",
            convert::type_name(config)
        ))
    })?;
    if let Err(e) = std::fs::metadata(&path) {
        return Err(convert::io_error(
            e.kind(),
            format!("cannot read config {}: {e}", path.display()),
        ));
    }
    Config::load(&path).map_err(|e| value_error(format!("{e:#}")))
}

/// Plans the scenario of `config`, turning the object to its goal by rolling within the ICRs
/// and switching fingers, as `icrflow plan` does (the same trajectory and summary; nothing is
/// written). `config` is a path to a TOML config or a dict shaped like one (relative file
/// names in a dict are relative to the working directory; `None` values are left out).
///
/// Returns a `Plan` (`summary` dict, `trajectory` dict of arrays, `switches`). A plan that
/// stops before its goal is a result (`summary["completed"]` is False, `stop_reason` says
/// why). Raises `ValueError` for a bad config (naming the key), `FileNotFoundError` for a
/// missing file, and `icrflow.IcrflowError` when the scenario is refused (not force closure,
/// below the margin, an unreachable contact, ...) with the CLI's message.
#[pyfunction]
pub fn plan(py: Python<'_>, config: &Bound<'_, PyAny>) -> PyResult<Plan> {
    let config = config_arg(config)?;
    let planned = py
        .detach(|| -> anyhow::Result<(Planned, Vec<u32>)> {
            let setup = Setup::new(&config)?;
            let plan = match setup.spatial_scenario(&config) {
                Some(spatial) => spatial.plan(&mut |_| {}),
                None => setup.scenario(&config).plan(&mut |_| {}),
            }
            .context("cannot plan")?;
            Ok((plan, setup.hand.fingers.iter().map(|f| f.id).collect()))
        })
        .map_err(|e| icrflow_error(format!("{e:#}")))?;
    let (plan, fingers) = planned;
    let summary = serde_json::to_value(&plan.summary).map_err(|e| icrflow_error(e.to_string()))?;
    let summary = json_to_py(py, &summary)?.cast_into::<PyDict>()?;
    let switches = PyList::empty(py);
    for s in &plan.steps {
        if let Some(sw) = &s.switch {
            let v = serde_json::to_value(sw).map_err(|e| icrflow_error(e.to_string()))?;
            let d = json_to_py(py, &v)?.cast_into::<PyDict>()?;
            d.set_item("step", s.step)?;
            switches.append(d)?;
        }
    }
    Ok(Plan {
        summary: summary.unbind(),
        trajectory: trajectory(py, &plan, &fingers)?.unbind(),
        switches: switches.unbind(),
    })
}

fn trajectory<'py>(
    py: Python<'py>,
    plan: &Planned,
    fingers: &[u32],
) -> PyResult<Bound<'py, PyDict>> {
    let (s, f) = (plan.steps.len(), fingers.len());
    let j = plan
        .steps
        .iter()
        .flat_map(|st| st.fingers.iter().map(|x| x.joints.len()))
        .max()
        .unwrap_or(0);
    let nan = Real::NAN;
    let mut contact = vec![-1_i64; s * f];
    let mut point = vec![nan; s * f * 3];
    let mut normal = vec![nan; s * f * 3];
    let mut angle = vec![nan; s * f];
    let mut cap = vec![nan; s * f];
    let mut tip_rotation = vec![nan; s * f];
    let mut tip_centre = vec![nan; s * f * 3];
    let mut joints = vec![nan; s * f * j];
    for (k, st) in plan.steps.iter().enumerate() {
        for state in &st.fingers {
            let Some(i) = fingers.iter().position(|&id| id == state.finger) else {
                continue;
            };
            let at = k * f + i;
            if let Some(c) = state.contact {
                contact[at] = c as i64;
            }
            if let Some(p) = state.point {
                point[3 * at..3 * at + 3].copy_from_slice(&p);
            }
            if let Some(n) = state.normal {
                normal[3 * at..3 * at + 3].copy_from_slice(&n);
            }
            // Degrees out, as in the plan's files (the same conversion as theirs).
            angle[at] = state.angle.map_or(nan, Real::to_degrees);
            cap[at] = state.cap_angle.map_or(nan, Real::to_degrees);
            tip_rotation[at] = state.tip_rotation.to_degrees();
            tip_centre[3 * at..3 * at + 3].copy_from_slice(&state.tip_centre);
            for (out, q) in joints[j * at..].iter_mut().zip(&state.joints) {
                *out = q.to_degrees();
            }
        }
    }
    let d = PyDict::new(py);
    d.set_item(
        "step",
        array_out(
            py,
            plan.steps.iter().map(|st| st.step as i64).collect(),
            &[s],
        ),
    )?;
    let phases: Vec<&str> = plan.steps.iter().map(|st| st.phase.name()).collect();
    d.set_item(
        "phase",
        py.import("numpy")?.call_method1("array", (phases,))?,
    )?;
    d.set_item(
        "rotation_deg",
        array_out(
            py,
            plan.steps
                .iter()
                .map(|st| st.rotation.to_degrees())
                .collect(),
            &[s],
        ),
    )?;
    d.set_item(
        "quality",
        array_out(py, plan.steps.iter().map(|st| st.quality).collect(), &[s]),
    )?;
    d.set_item(
        "fingers",
        array_out(py, fingers.iter().map(|&x| i64::from(x)).collect(), &[f]),
    )?;
    d.set_item("contact", array_out(py, contact, &[s, f]))?;
    d.set_item("point", array_out(py, point, &[s, f, 3]))?;
    d.set_item("normal", array_out(py, normal, &[s, f, 3]))?;
    d.set_item("angle_deg", array_out(py, angle, &[s, f]))?;
    d.set_item("cap_angle_deg", array_out(py, cap, &[s, f]))?;
    d.set_item("tip_rotation_deg", array_out(py, tip_rotation, &[s, f]))?;
    d.set_item("tip_centre", array_out(py, tip_centre, &[s, f, 3]))?;
    d.set_item("joints_deg", array_out(py, joints, &[s, f, j]))?;
    Ok(d)
}
