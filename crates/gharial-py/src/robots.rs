//! `gharial.robots`: multibody models from URDF, their algorithms on numpy arrays, and
//! the robotics spaces, dynamics and residuals.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};

use faer::{Mat, MatRef};
use gharial_multibody::spatial::{Mat3, Se3, Vec3};
use gharial_multibody::{self as mb, Data, Model, ReferenceFrame, RootJoint};
use gharial_robotics::residuals::{CenterOfMassTranslationResidual, FramePlacementResidual, FrameTranslationResidual};
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConfiguration, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics,
    MultibodyPhaseSpace, contacts_at_frames, set_contact_references,
};
use numpy::{PyArray1, PyArray2};
use pyo3::PyClassInitializer;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{array1, array2, err, matrix, mb_err, value_error, vector};
use crate::dynamics::PyOde;
use crate::functions::PyStageFunction;
use crate::spaces::PyManifold;
use gharial_problems::robots;

/// A built-in robot: name, URDF, SRDF and root joint.
type Builtin = (&'static str, &'static str, Option<&'static str>, RootJoint);

/// The robots embedded in the package (example-robot-data 5.0.0).
const BUILTIN: [Builtin; 5] = [
    ("ur5", robots::UR5_URDF, Some(robots::UR5_SRDF), RootJoint::Fixed),
    ("ur10", robots::UR10_URDF, None, RootJoint::Fixed),
    ("double_pendulum", robots::DOUBLE_PENDULUM_URDF, None, RootJoint::Fixed),
    (
        "solo12",
        robots::SOLO_URDF,
        Some(robots::SOLO_SRDF),
        RootJoint::FreeFlyer,
    ),
    ("quadrotor", robots::HECTOR_URDF, None, RootJoint::FreeFlyer),
];

/// A multibody model (Pinocchio's `Model`, with its own `Data` inside).
#[pyclass(frozen, name = "RobotModel", module = "gharial.robots")]
pub struct PyRobotModel {
    model: Arc<Model>,
    data: Mutex<Data>,
}

impl PyRobotModel {
    /// Wraps a model, with a fresh `Data`.
    fn wrap(model: Arc<Model>) -> Self {
        let data = Mutex::new(model.create_data());
        Self { model, data }
    }

    /// The multibody model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The model's `Data` (a panic in an earlier call leaves it usable).
    fn data(&self) -> MutexGuard<'_, Data> {
        self.data.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A configuration argument (`nq`).
    fn q(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        vector(obj, what, Some(self.model.nq()))
    }

    /// A velocity-like argument (`nv`).
    fn v(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        vector(obj, what, Some(self.model.nv()))
    }

    /// The id of a frame, by name.
    fn frame(&self, name: &str) -> PyResult<usize> {
        self.model.frame_id(name).map_err(mb_err)
    }
}

#[pymethods]
impl PyRobotModel {
    /// The robot's name.
    #[getter]
    fn name(&self) -> &str {
        &self.model.name
    }
    /// Configuration size.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq()
    }
    /// Velocity size.
    #[getter]
    fn nv(&self) -> usize {
        self.model.nv()
    }
    /// Number of joints (the universe included).
    #[getter]
    fn njoints(&self) -> usize {
        self.model.njoints()
    }
    /// Number of frames (the universe included).
    #[getter]
    fn nframes(&self) -> usize {
        self.model.nframes()
    }
    /// Joint names (index = joint id; `universe` first).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model.joint_names().to_vec()
    }
    /// Frame names (index = frame id).
    #[getter]
    fn frame_names(&self) -> Vec<String> {
        self.model.frames().iter().map(|f| f.name.clone()).collect()
    }
    /// Total mass of the bodies.
    #[getter]
    fn total_mass(&self) -> f64 {
        self.model.total_mass()
    }
    /// Gravity (3, world).
    #[getter]
    fn gravity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.model.gravity.linear.as_slice())
    }
    /// Lower position limits (nq).
    #[getter]
    fn lower_position_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.model.lower_position_limit)
    }
    /// Upper position limits (nq).
    #[getter]
    fn upper_position_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.model.upper_position_limit)
    }
    /// Velocity limits (nv).
    #[getter]
    fn velocity_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.model.velocity_limit)
    }
    /// Effort limits (nv).
    #[getter]
    fn effort_limit<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.model.effort_limit)
    }
    /// The named reference configurations of the SRDF (name → q).
    #[getter]
    fn reference_configurations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, q) in &self.model.reference_configurations {
            d.set_item(name, array1(py, q))?;
        }
        Ok(d)
    }

    /// The neutral configuration.
    fn neutral<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &mb::neutral(&self.model))
    }
    /// The id of the frame `name` (`GharialError` if unknown).
    fn frame_id(&self, name: &str) -> PyResult<usize> {
        self.frame(name)
    }
    /// The id of the joint `name` (`GharialError` if unknown).
    fn joint_id(&self, name: &str) -> PyResult<usize> {
        self.model.joint_id(name).map_err(mb_err)
    }
    /// The SRDF reference configuration `name` (`GharialError` if unknown).
    fn reference_configuration<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(array1(py, self.model.reference_configuration(name).map_err(mb_err)?))
    }

    fn __repr__(&self) -> String {
        let m = &self.model;
        format!(
            "RobotModel(name={:?}, nq={}, nv={}, njoints={})",
            m.name,
            m.nq(),
            m.nv(),
            m.njoints()
        )
    }
}

/// The root joint of a URDF.
fn root(free_flyer: bool) -> RootJoint {
    if free_flyer {
        RootJoint::FreeFlyer
    } else {
        RootJoint::Fixed
    }
}

/// A loaded model, with its SRDF (as text) if any.
fn finish(model: mb::Result<Model>, srdf: Option<&str>) -> PyResult<PyRobotModel> {
    let mut model = model.map_err(mb_err)?;
    if let Some(s) = srdf {
        model.load_srdf_str(s).map_err(mb_err)?;
    }
    Ok(PyRobotModel::wrap(Arc::new(model)))
}

/// Loads a URDF file (`free_flyer`: a free-flyer root joint; `srdf`: an SRDF file).
#[pyfunction]
#[pyo3(signature = (path, free_flyer = false, srdf = None))]
fn load_urdf(path: PathBuf, free_flyer: bool, srdf: Option<PathBuf>) -> PyResult<PyRobotModel> {
    let srdf = match srdf {
        Some(p) => Some(std::fs::read_to_string(&p).map_err(|e| mb_err(io_error(&p, e)))?),
        None => None,
    };
    finish(Model::from_urdf_file(path, root(free_flyer)), srdf.as_deref())
}

/// A file that could not be read, as a multibody error.
fn io_error(path: &std::path::Path, e: std::io::Error) -> mb::Error {
    mb::Error::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Loads a URDF from its XML text (`srdf`: the SRDF's text).
#[pyfunction]
#[pyo3(signature = (xml, free_flyer = false, srdf = None))]
fn load_urdf_string(xml: &str, free_flyer: bool, srdf: Option<&str>) -> PyResult<PyRobotModel> {
    finish(Model::from_urdf_str(xml, root(free_flyer)), srdf)
}

/// Loads a robot embedded in the package (see `builtin_robots()`).
#[pyfunction]
fn load_builtin(name: &str) -> PyResult<PyRobotModel> {
    let (_, urdf, srdf, root) = BUILTIN.iter().find(|b| b.0 == name).ok_or_else(|| {
        value_error(format!(
            "load_builtin: unknown robot {name:?}, expected one of {:?}",
            builtin_robots()
        ))
    })?;
    finish(Model::from_urdf_str(urdf, *root), *srdf)
}

/// The names of the robots embedded in the package.
#[pyfunction]
fn builtin_robots() -> Vec<&'static str> {
    BUILTIN.iter().map(|b| b.0).collect()
}

type Arr1<'py> = PyResult<Bound<'py, PyArray1<f64>>>;
type Arr2<'py> = PyResult<Bound<'py, PyArray2<f64>>>;
type Triple<'py> = PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
)>;

/// Inverse dynamics `τ = RNEA(q, v, a)`.
#[pyfunction]
fn rnea<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    a: &Bound<'py, PyAny>,
) -> Arr1<'py> {
    let m = model.get();
    let (q, v, a) = (m.q(q, "q")?, m.v(v, "v")?, m.v(a, "a")?);
    Ok(array1(
        model.py(),
        mb::rnea(&m.model, &mut m.data(), &q, &v, &a).map_err(mb_err)?,
    ))
}

/// Forward dynamics `a = ABA(q, v, τ)`.
#[pyfunction]
fn aba<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
) -> Arr1<'py> {
    let m = model.get();
    let (q, v, tau) = (m.q(q, "q")?, m.v(v, "v")?, m.v(tau, "tau")?);
    Ok(array1(
        model.py(),
        mb::aba(&m.model, &mut m.data(), &q, &v, &tau).map_err(mb_err)?,
    ))
}

/// The joint-space inertia matrix `M(q)` (full, symmetric).
#[pyfunction]
fn crba<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>) -> Arr2<'py> {
    let m = model.get();
    let q = m.q(q, "q")?;
    Ok(array2(
        model.py(),
        mb::crba(&m.model, &mut m.data(), &q).map_err(mb_err)?,
    ))
}

/// The generalized gravity `g(q)`.
#[pyfunction]
fn generalized_gravity<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>) -> Arr1<'py> {
    let m = model.get();
    let q = m.q(q, "q")?;
    Ok(array1(
        model.py(),
        mb::generalized_gravity(&m.model, &mut m.data(), &q).map_err(mb_err)?,
    ))
}

/// The nonlinear effects `b(q, v) = C(q, v) v + g(q)`.
#[pyfunction]
fn nonlinear_effects<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>, v: &Bound<'py, PyAny>) -> Arr1<'py> {
    let m = model.get();
    let (q, v) = (m.q(q, "q")?, m.v(v, "v")?);
    Ok(array1(
        model.py(),
        mb::nonlinear_effects(&m.model, &mut m.data(), &q, &v).map_err(mb_err)?,
    ))
}

/// Three matrices of the data as numpy arrays.
fn three<'py>(py: Python<'py>, d: &Data, f: [fn(&Data) -> MatRef<'_, f64>; 3]) -> Triple<'py> {
    Ok((array2(py, f[0](d)), array2(py, f[1](d)), array2(py, f[2](d))))
}

/// `(∂τ/∂q, ∂τ/∂v, M)` of the RNEA at `(q, v, a)` (q-derivatives along `q ⊕ δ`).
#[pyfunction]
fn compute_rnea_derivatives<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    a: &Bound<'py, PyAny>,
) -> Triple<'py> {
    let m = model.get();
    let (q, v, a) = (m.q(q, "q")?, m.v(v, "v")?, m.v(a, "a")?);
    let mut d = m.data();
    mb::compute_rnea_derivatives(&m.model, &mut d, &q, &v, &a).map_err(mb_err)?;
    three(model.py(), &d, [Data::dtau_dq, Data::dtau_dv, Data::mass_matrix])
}

/// `(∂a/∂q, ∂a/∂v, M⁻¹)` of the ABA at `(q, v, τ)`.
#[pyfunction]
fn compute_aba_derivatives<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
) -> Triple<'py> {
    let m = model.get();
    let (q, v, tau) = (m.q(q, "q")?, m.v(v, "v")?, m.v(tau, "tau")?);
    let mut d = m.data();
    mb::compute_aba_derivatives(&m.model, &mut d, &q, &v, &tau).map_err(mb_err)?;
    three(model.py(), &d, [Data::ddq_dq, Data::ddq_dv, Data::minv])
}

/// A placement as numpy arrays `(R 3x3, p 3)`.
type Placement<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// A placement as `(R 3x3, p 3)`.
fn se3_to_py<'py>(py: Python<'py>, m: &Se3) -> Placement<'py> {
    let r = Mat::from_fn(3, 3, |i, j| m.rotation[(i, j)]);
    (array2(py, r.as_ref()), array1(py, m.translation.as_slice()))
}

/// A placement from `(R 3x3, p 3)` array-likes.
fn se3_from_py(r: &Bound<'_, PyAny>, p: &Bound<'_, PyAny>, what: &str) -> PyResult<Se3> {
    let r = matrix(r, &format!("{what} R"), Some((3, 3)))?;
    let p = vector(p, &format!("{what} p"), Some(3))?;
    Ok(Se3::new(Mat3::from_fn(|i, j| r[(i, j)]), Vec3::new(p[0], p[1], p[2])))
}

/// The world placement `(R, p)` of a frame at `q`.
#[pyfunction]
fn frame_placement<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    frame: &str,
) -> PyResult<Placement<'py>> {
    let m = model.get();
    let (q, f) = (m.q(q, "q")?, m.frame(frame)?);
    let mut d = m.data();
    mb::forward_kinematics_placements(&m.model, &mut d, &q).map_err(mb_err)?;
    mb::update_frame_placements(&m.model, &mut d).map_err(mb_err)?;
    Ok(se3_to_py(model.py(), d.frame_placement(f)))
}

/// A reference frame by name.
pub(crate) fn reference_frame(name: &str) -> PyResult<ReferenceFrame> {
    match name {
        "local_world_aligned" | "LOCAL_WORLD_ALIGNED" => Ok(ReferenceFrame::LocalWorldAligned),
        "world" | "WORLD" => Ok(ReferenceFrame::World),
        "local" | "LOCAL" => Ok(ReferenceFrame::Local),
        _ => Err(value_error(format!(
            "reference: expected \"local_world_aligned\", \"world\" or \"local\", got {name:?}"
        ))),
    }
}

/// The Jacobian (6 x nv, `[linear; angular]`) of a frame at `q`, in `reference`.
#[pyfunction]
#[pyo3(signature = (model, q, frame, reference = "local_world_aligned"))]
fn frame_jacobian<'py>(
    model: &Bound<'py, PyRobotModel>,
    q: &Bound<'py, PyAny>,
    frame: &str,
    reference: &str,
) -> Arr2<'py> {
    let m = model.get();
    let (q, f, rf) = (m.q(q, "q")?, m.frame(frame)?, reference_frame(reference)?);
    let mut j = Mat::zeros(6, m.model.nv());
    let mut d = m.data();
    mb::compute_joint_jacobians(&m.model, &mut d, &q).map_err(mb_err)?;
    mb::frame_jacobian(&m.model, &d, f, rf, j.as_mut()).map_err(mb_err)?;
    Ok(array2(model.py(), j.as_ref()))
}

/// The centre of mass (3, world) at `q`.
#[pyfunction]
fn center_of_mass<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>) -> Arr1<'py> {
    let m = model.get();
    let q = m.q(q, "q")?;
    let zeros = vec![0.0; m.model.nv()];
    let c = *mb::center_of_mass(&m.model, &mut m.data(), &q, &zeros, &zeros).map_err(mb_err)?;
    Ok(array1(model.py(), c.as_slice()))
}

/// The Jacobian (3 x nv, world) of the centre of mass at `q`.
#[pyfunction]
fn jacobian_center_of_mass<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>) -> Arr2<'py> {
    let m = model.get();
    let q = m.q(q, "q")?;
    Ok(array2(
        model.py(),
        mb::jacobian_center_of_mass(&m.model, &mut m.data(), &q).map_err(mb_err)?,
    ))
}

/// `q ⊕ v`.
#[pyfunction]
fn integrate<'py>(model: &Bound<'py, PyRobotModel>, q: &Bound<'py, PyAny>, v: &Bound<'py, PyAny>) -> Arr1<'py> {
    let m = model.get();
    let (q, v) = (m.q(q, "q")?, m.v(v, "v")?);
    let mut out = vec![0.0; m.model.nq()];
    mb::integrate(&m.model, &q, &v, &mut out).map_err(mb_err)?;
    Ok(array1(model.py(), &out))
}

/// `q1 ⊖ q0`, the velocity (nv) leading from `q0` to `q1` in unit time.
#[pyfunction]
fn difference<'py>(model: &Bound<'py, PyRobotModel>, q0: &Bound<'py, PyAny>, q1: &Bound<'py, PyAny>) -> Arr1<'py> {
    let m = model.get();
    let (q0, q1) = (m.q(q0, "q0")?, m.q(q1, "q1")?);
    let mut out = vec![0.0; m.model.nv()];
    mb::difference(&m.model, &q0, &q1, &mut out).map_err(mb_err)?;
    Ok(array1(model.py(), &out))
}

/// The configuration space of a multibody model (`nx = nq`, `ndx = nv`).
#[pyclass(extends = PyManifold, frozen, name = "MultibodyConfiguration", module = "gharial.robots")]
pub struct PyMultibodyConfiguration {
    space: Arc<MultibodyConfiguration>,
}

impl PyMultibodyConfiguration {
    /// The Python object of a configuration space.
    fn init(space: Arc<MultibodyConfiguration>) -> PyClassInitializer<Self> {
        PyClassInitializer::from(PyManifold::new(space.clone())).add_subclass(Self { space })
    }
}

#[pymethods]
impl PyMultibodyConfiguration {
    #[new]
    fn new(model: &Bound<'_, PyRobotModel>) -> PyClassInitializer<Self> {
        Self::init(Arc::new(MultibodyConfiguration::new(model.get().model.clone())))
    }

    /// The model.
    #[getter]
    fn model(&self) -> PyRobotModel {
        PyRobotModel::wrap(self.space.model().clone())
    }
}

/// The phase space `x = (q, v)` of a multibody model (ALIGATOR's `MultibodyPhaseSpace`).
#[pyclass(extends = PyManifold, frozen, name = "MultibodyPhaseSpace", module = "gharial.robots")]
pub struct PyMultibodyPhaseSpace {
    space: Arc<MultibodyPhaseSpace>,
}

#[pymethods]
impl PyMultibodyPhaseSpace {
    #[new]
    fn new(model: &Bound<'_, PyRobotModel>) -> PyClassInitializer<Self> {
        let space = Arc::new(MultibodyPhaseSpace::new(model.get().model.clone()));
        PyClassInitializer::from(PyManifold::new(space.clone())).add_subclass(Self { space })
    }

    /// The model.
    #[getter]
    fn model(&self) -> PyRobotModel {
        PyRobotModel::wrap(self.space.model().clone())
    }
    /// Configuration size.
    #[getter]
    fn nq(&self) -> usize {
        self.space.nq()
    }
    /// Velocity size.
    #[getter]
    fn nv(&self) -> usize {
        self.space.nv()
    }
    /// The configuration space of `q`.
    #[getter]
    fn configuration<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyMultibodyConfiguration>> {
        Bound::new(py, PyMultibodyConfiguration::init(self.space.configuration().clone()))
    }
}

/// The phase space of a Python `MultibodyPhaseSpace`.
pub(crate) fn phase(space: &Bound<'_, PyMultibodyPhaseSpace>) -> Arc<MultibodyPhaseSpace> {
    space.get().space.clone()
}

/// The actuation `B` given (nv x nu), or by default the identity on a fixed base and
/// `[0; I]` under a free-flyer root.
fn actuation(model: &Model, b: Option<&Bound<'_, PyAny>>) -> PyResult<Actuation> {
    match b {
        Some(b) => {
            let b = matrix(b, "actuation", None)?;
            if b.nrows() != model.nv() {
                return Err(value_error(format!(
                    "actuation: expected {} rows (nv), got {}",
                    model.nv(),
                    b.nrows()
                )));
            }
            Actuation::matrix(model, b.as_ref()).map_err(err)
        }
        None => Ok(Actuation::floating_base(model).unwrap_or_else(|_| Actuation::full(model))),
    }
}

/// The ODE base of a multibody ODE (with its configuration space, for
/// `IntegratorSemiImplEuler`).
fn ode_base(ode: Arc<dyn gharial::dynamics::Ode>, space: &MultibodyPhaseSpace) -> PyOde {
    PyOde::rust(ode, Some(space.configuration().clone()))
}

/// Free forward dynamics `ẋ = (v, ABA(q, v, B u))` (ALIGATOR's `MultibodyFreeFwdDynamics`).
#[pyclass(extends = PyOde, name = "MultibodyFreeFwdDynamics", module = "gharial.robots")]
pub struct PyFreeFwdDynamics {
    ode: Arc<MultibodyFreeFwdDynamics>,
}

#[pymethods]
impl PyFreeFwdDynamics {
    #[new]
    #[pyo3(signature = (space, actuation = None))]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        actuation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let space = phase(space);
        let b = self::actuation(space.model(), actuation)?;
        let ode = Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), b).map_err(err)?);
        Ok(PyClassInitializer::from(ode_base(ode.clone(), &space)).add_subclass(Self { ode }))
    }

    /// The actuation matrix `B` (nv x nu).
    #[getter]
    fn actuation_matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        array2(py, self.ode.actuation().to_matrix().as_ref())
    }

    /// The controls `u = B⁺ g(q)` that hold the robot still at `q`.
    fn gravity_compensation<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> Arr1<'py> {
        let q = vector(q, "q", Some(self.ode.phase_space().nq()))?;
        Ok(array1(py, &self.ode.gravity_compensation(&q).map_err(err)?))
    }
}

/// The contact spec of a type (`"3d"`, `"6d"`), a reference frame and gains.
fn contact_spec(kind: &str, reference: &str, kp: f64, kd: f64) -> PyResult<ContactSpec> {
    let rf = reference_frame(reference)?;
    let spec = match kind {
        "3d" | "3D" => ContactSpec::point(rf),
        "6d" | "6D" => ContactSpec::frame(rf),
        _ => {
            return Err(value_error(format!(
                "contact_type: expected \"3d\" or \"6d\", got {kind:?}"
            )));
        }
    };
    Ok(spec.with_gains(kp, kd))
}

/// Forward dynamics with rigid contacts at frames (ALIGATOR's
/// `MultibodyConstraintFwdDynamics`): `M a + b = B u + Jcᵀ λ`, `Jc a + γ = −Kp c − Kd ċ`.
///
/// `contact_type`: `"3d"` (point) or `"6d"` (frame); `reference`: `"local_world_aligned"`
/// or `"local"`; `kp`, `kd`: Baumgarte gains; `q_ref`: the configuration whose contact
/// placements the `kp` term pulls towards (without it, the world origin).
#[pyclass(extends = PyOde, name = "MultibodyConstraintFwdDynamics", module = "gharial.robots")]
pub struct PyConstraintFwdDynamics {
    pub(crate) ode: Arc<MultibodyConstraintFwdDynamics>,
}

#[pymethods]
impl PyConstraintFwdDynamics {
    #[new]
    #[pyo3(signature = (space, actuation, contact_frames, contact_type = "3d", reference = "local_world_aligned",
                        kp = 0.0, kd = 0.0, q_ref = None))]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        actuation: Option<&Bound<'_, PyAny>>,
        contact_frames: Vec<String>,
        contact_type: &str,
        reference: &str,
        kp: f64,
        kd: f64,
        q_ref: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let space = phase(space);
        let model = space.model();
        let b = self::actuation(model, actuation)?;
        let frames: Vec<&str> = contact_frames.iter().map(String::as_str).collect();
        let spec = contact_spec(contact_type, reference, kp, kd)?;
        let mut contacts = contacts_at_frames(model, &frames, spec).map_err(err)?;
        if let Some(q) = q_ref {
            let q = vector(q, "q_ref", Some(model.nq()))?;
            set_contact_references(model, &mut contacts, &q).map_err(err)?;
        }
        let ode = Arc::new(MultibodyConstraintFwdDynamics::new(space.clone(), b, contacts).map_err(err)?);
        Ok(PyClassInitializer::from(ode_base(ode.clone(), &space)).add_subclass(Self { ode }))
    }

    /// Number of constraint rows (3 or 6 per contact).
    #[getter]
    fn nc(&self) -> usize {
        self.ode.nc()
    }

    /// The actuation matrix `B` (nv x nu).
    #[getter]
    fn actuation_matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        array2(py, self.ode.actuation().to_matrix().as_ref())
    }

    /// The stacked contact forces `λ` (nc) at `(x, u)`, in each contact's reference frame.
    fn contact_forces<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>, u: &Bound<'py, PyAny>) -> Arr1<'py> {
        let s = self.ode.phase_space();
        let x = vector(x, "x", Some(s.nq() + s.nv()))?;
        let u = vector(u, "u", Some(self.ode.actuation().nu()))?;
        let mut d = self.ode.create_contact_data();
        Ok(array1(py, self.ode.contact_forces(&x, &u, &mut d).map_err(err)?))
    }
}

/// A Rust unary residual lifted to a stage function with `nu` controls.
pub(crate) fn lifted(f: Arc<dyn gharial::functions::UnaryFunction>, nu: usize) -> PyStageFunction {
    PyStageFunction::rust(Arc::new(gharial::functions::Unary::new(f, nu)), Vec::new())
}

/// `r(x) = p_f(q) − p_ref` (3, world; ALIGATOR's `FrameTranslationResidual`).
#[pyclass(extends = PyStageFunction, name = "FrameTranslationResidual", module = "gharial.robots")]
pub struct PyFrameTranslation {
    f: Arc<FrameTranslationResidual>,
}

#[pymethods]
impl PyFrameTranslation {
    #[new]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        nu: usize,
        frame: &str,
        p_ref: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let p = vector(p_ref, "FrameTranslationResidual p_ref", Some(3))?;
        let f = Arc::new(FrameTranslationResidual::new(&phase(space), frame, &p).map_err(err)?);
        Ok(PyClassInitializer::from(lifted(f.clone(), nu)).add_subclass(Self { f }))
    }

    /// The target position (settable between solves).
    #[getter]
    fn get_target<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.f.target())
    }
    #[setter]
    fn set_target(&self, p_ref: &Bound<'_, PyAny>) -> PyResult<()> {
        self.f.set_target(&vector(p_ref, "target", Some(3))?).map_err(err)
    }
    /// The frame's id.
    #[getter]
    fn frame_id(&self) -> usize {
        self.f.frame_id()
    }
}

/// `r(x) = log6(M_ref⁻¹ oMf(q))` (6, `[linear, angular]`; ALIGATOR's
/// `FramePlacementResidual`).
#[pyclass(extends = PyStageFunction, name = "FramePlacementResidual", module = "gharial.robots")]
pub struct PyFramePlacement {
    f: Arc<FramePlacementResidual>,
}

#[pymethods]
impl PyFramePlacement {
    #[new]
    #[pyo3(signature = (space, nu, frame, r_ref, p_ref))]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        nu: usize,
        frame: &str,
        r_ref: &Bound<'_, PyAny>,
        p_ref: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let m = se3_from_py(r_ref, p_ref, "FramePlacementResidual")?;
        let f = Arc::new(FramePlacementResidual::new(&phase(space), frame, &m).map_err(err)?);
        Ok(PyClassInitializer::from(lifted(f.clone(), nu)).add_subclass(Self { f }))
    }

    /// The target placement `(R, p)` (settable between solves).
    #[getter]
    fn get_target<'py>(&self, py: Python<'py>) -> Placement<'py> {
        se3_to_py(py, &self.f.target())
    }
    #[setter]
    fn set_target(&self, target: (Bound<'_, PyAny>, Bound<'_, PyAny>)) -> PyResult<()> {
        self.f
            .set_target(&se3_from_py(&target.0, &target.1, "target")?)
            .map_err(err)
    }
    /// The frame's id.
    #[getter]
    fn frame_id(&self) -> usize {
        self.f.frame_id()
    }
}

/// `r(x) = c(q) − c_ref` (3, world; ALIGATOR's `CenterOfMassTranslationResidual`).
#[pyclass(extends = PyStageFunction, name = "CenterOfMassTranslationResidual", module = "gharial.robots")]
pub struct PyComTranslation {
    f: Arc<CenterOfMassTranslationResidual>,
}

#[pymethods]
impl PyComTranslation {
    #[new]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        nu: usize,
        c_ref: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let c = vector(c_ref, "CenterOfMassTranslationResidual c_ref", Some(3))?;
        let f = Arc::new(CenterOfMassTranslationResidual::new(&phase(space), &c).map_err(err)?);
        Ok(PyClassInitializer::from(lifted(f.clone(), nu)).add_subclass(Self { f }))
    }

    /// The target centre of mass (settable between solves).
    #[getter]
    fn get_target<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.f.target())
    }
    #[setter]
    fn set_target(&self, c_ref: &Bound<'_, PyAny>) -> PyResult<()> {
        self.f.set_target(&vector(c_ref, "target", Some(3))?).map_err(err)
    }
}

/// Registers the classes and functions of `gharial.robots`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRobotModel>()?;
    m.add_class::<PyMultibodyConfiguration>()?;
    m.add_class::<PyMultibodyPhaseSpace>()?;
    m.add_class::<PyFreeFwdDynamics>()?;
    m.add_class::<PyConstraintFwdDynamics>()?;
    m.add_class::<PyFrameTranslation>()?;
    m.add_class::<PyFramePlacement>()?;
    m.add_class::<PyComTranslation>()?;
    crate::robot_residuals::register(m)?;
    for f in [
        wrap_pyfunction!(load_urdf, m)?,
        wrap_pyfunction!(load_urdf_string, m)?,
        wrap_pyfunction!(load_builtin, m)?,
        wrap_pyfunction!(builtin_robots, m)?,
        wrap_pyfunction!(rnea, m)?,
        wrap_pyfunction!(aba, m)?,
        wrap_pyfunction!(crba, m)?,
        wrap_pyfunction!(generalized_gravity, m)?,
        wrap_pyfunction!(nonlinear_effects, m)?,
        wrap_pyfunction!(compute_rnea_derivatives, m)?,
        wrap_pyfunction!(compute_aba_derivatives, m)?,
        wrap_pyfunction!(frame_placement, m)?,
        wrap_pyfunction!(frame_jacobian, m)?,
        wrap_pyfunction!(center_of_mass, m)?,
        wrap_pyfunction!(jacobian_center_of_mass, m)?,
        wrap_pyfunction!(integrate, m)?,
        wrap_pyfunction!(difference, m)?,
    ] {
        m.add_function(f)?;
    }
    Ok(())
}
