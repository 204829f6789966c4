//! Models written in Python: a cost, a stage function or an ODE subclassed in Python
//! becomes a Rust model that calls back into the interpreter (taking the GIL).
//!
//! The model's output shapes are checked once, when it enters a Rust object, by calling
//! it at the neutral state and zero control. An exception raised later (during a solve)
//! is kept in the model's [`Slot`], the model writes NaN so that the solver stops with a
//! non-finite status, and the solve raises the exception with the stage index (see
//! `problem::raise_python_errors`).

use std::sync::{Arc, Mutex};

use faer::{Col, Mat};
use gharial::costs::{Cost, CostData};
use gharial::dynamics::{Ode, OdeData};
use gharial::functions::{StageFunction, StageFunctionData};
use gharial::spaces::Manifold;
use pyo3::prelude::*;

use crate::convert::{array1, value_error};

/// Where a Python model keeps the first exception its code raised.
#[derive(Debug)]
pub struct Slot {
    /// What the model is (its Python class name), for messages.
    pub label: String,
    err: Mutex<Option<PyErr>>,
}

impl Slot {
    fn new(label: String) -> Arc<Self> {
        Arc::new(Self {
            label,
            err: Mutex::new(None),
        })
    }

    fn failed(&self) -> bool {
        self.err.lock().map(|e| e.is_some()).unwrap_or(true)
    }

    fn record(&self, e: PyErr) {
        if let Ok(mut slot) = self.err.lock()
            && slot.is_none()
        {
            *slot = Some(e);
        }
    }

    /// Takes the recorded exception, if any.
    pub fn take(&self) -> Option<PyErr> {
        self.err.lock().ok().and_then(|mut e| e.take())
    }
}

/// The slots of the Python models inside a Rust object (empty for pure Rust models).
pub type Slots = Vec<Arc<Slot>>;

/// Sizes of a model: state (`nx`, `ndx`), control `nu`, output `nr`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Dims {
    /// Representation size of the state.
    pub nx: usize,
    /// Tangent size of the state.
    pub ndx: usize,
    /// Control size.
    pub nu: usize,
    /// Output size (functions).
    pub nr: usize,
}

fn class_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// Copies a returned array into `out`, checking its shape (rows, cols).
fn read_into(obj: &Bound<'_, PyAny>, what: &str, rows: usize, cols: Option<usize>, out: &mut [f64]) -> PyResult<()> {
    match cols {
        None => {
            let v = crate::convert::vector(obj, what, Some(rows))?;
            out.copy_from_slice(&v);
        }
        Some(c) => {
            let m = crate::convert::matrix(obj, what, Some((rows, c)))?;
            for i in 0..rows {
                for j in 0..c {
                    out[i * c + j] = m[(i, j)];
                }
            }
        }
    }
    Ok(())
}

fn write_mat(m: &mut Mat<f64>, s: &[f64]) {
    let c = m.ncols();
    for i in 0..m.nrows() {
        for j in 0..c {
            m[(i, j)] = s[i * c + j];
        }
    }
}

fn write_col(v: &mut Col<f64>, s: &[f64]) {
    for (i, x) in s.iter().enumerate() {
        v[i] = *x;
    }
}

/// The call `obj.method(x, u)` returning a tuple of `shapes.len()` arrays (or one array
/// when `shapes` has one entry), copied row-major into `bufs`.
fn call_arrays(
    obj: &Bound<'_, PyAny>,
    method: &str,
    x: &[f64],
    u: &[f64],
    shapes: &[(&str, usize, Option<usize>)],
    bufs: &mut [Vec<f64>],
) -> PyResult<()> {
    let py = obj.py();
    let out = obj.call_method1(method, (array1(py, x), array1(py, u)))?;
    let name = class_name(obj);
    if shapes.len() == 1 {
        let (what, r, c) = shapes[0];
        return read_into(&out, &format!("{name}.{method}: {what}"), r, c, &mut bufs[0]);
    }
    let items: Vec<Bound<'_, PyAny>> = out
        .try_iter()
        .map_err(|_| {
            value_error(format!(
                "{name}.{method}: must return a tuple of {} arrays",
                shapes.len()
            ))
        })?
        .collect::<PyResult<_>>()?;
    if items.len() != shapes.len() {
        return Err(value_error(format!(
            "{name}.{method}: must return {} arrays, returned {}",
            shapes.len(),
            items.len()
        )));
    }
    for ((item, (what, r, c)), buf) in items.iter().zip(shapes).zip(bufs.iter_mut()) {
        read_into(item, &format!("{name}.{method}: {what}"), *r, *c, buf)?;
    }
    Ok(())
}

fn buffers(shapes: &[(&str, usize, Option<usize>)]) -> Vec<Vec<f64>> {
    shapes.iter().map(|(_, r, c)| vec![0.0; r * c.unwrap_or(1)]).collect()
}

/// One call into Python with the GIL held: `None` if the model failed before, or if
/// the call raises (the exception is kept in `slot`).
fn attach_guarded<T>(slot: &Slot, f: impl FnOnce(Python<'_>) -> PyResult<T>) -> Option<T> {
    if slot.failed() {
        return None;
    }
    Python::attach(|py| f(py).map_err(|e| slot.record(e)).ok())
}

/// The arrays `obj.method(x, u)` returns, shapes checked, or NaN arrays when the model
/// failed (see [`attach_guarded`]).
fn call_guarded(
    slot: &Slot,
    obj: &Py<PyAny>,
    method: &str,
    x: &[f64],
    u: &[f64],
    shapes: &[(&str, usize, Option<usize>)],
) -> Vec<Vec<f64>> {
    let mut bufs = buffers(shapes);
    if attach_guarded(slot, |py| call_arrays(obj.bind(py), method, x, u, shapes, &mut bufs)).is_none() {
        bufs.iter_mut().for_each(|b| b.fill(f64::NAN));
    }
    bufs
}

fn neutral(space: &dyn Manifold) -> Vec<f64> {
    let mut x = vec![0.0; space.nx()];
    space.neutral(&mut x);
    x
}

/// A cost subclassed in Python: `evaluate(x, u) -> float` and
/// `derivatives(x, u) -> (lx, lu, lxx, lxu, luu)`.
pub struct PyCostModel {
    obj: Py<PyAny>,
    dims: Dims,
    slot: Arc<Slot>,
}

impl PyCostModel {
    fn shapes(&self) -> [(&'static str, usize, Option<usize>); 5] {
        let Dims { ndx, nu, .. } = self.dims;
        [
            ("lx", ndx, None),
            ("lu", nu, None),
            ("lxx", ndx, Some(ndx)),
            ("lxu", ndx, Some(nu)),
            ("luu", nu, Some(nu)),
        ]
    }

    /// Wraps `obj` after one checked call of each method at the neutral state.
    pub fn new(obj: &Bound<'_, PyAny>, space: &dyn Manifold, nu: usize) -> PyResult<(Arc<Self>, Arc<Slot>)> {
        let dims = Dims {
            nx: space.nx(),
            ndx: space.ndx(),
            nu,
            nr: 0,
        };
        let slot = Slot::new(class_name(obj));
        let model = Self {
            obj: obj.clone().unbind(),
            dims,
            slot: slot.clone(),
        };
        let (x, u) = (neutral(space), vec![0.0; nu]);
        let v = obj.call_method1("evaluate", (array1(obj.py(), &x), array1(obj.py(), &u)))?;
        v.extract::<f64>()
            .map_err(|_| value_error(format!("{}.evaluate: must return a float", slot.label)))?;
        let shapes = model.shapes();
        call_arrays(obj, "derivatives", &x, &u, &shapes, &mut buffers(&shapes))?;
        Ok((Arc::new(model), slot))
    }
}

impl Cost for PyCostModel {
    fn nx(&self) -> usize {
        self.dims.nx
    }
    fn ndx(&self) -> usize {
        self.dims.ndx
    }
    fn nu(&self) -> usize {
        self.dims.nu
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        data.value = attach_guarded(&self.slot, |py| {
            let v = self
                .obj
                .bind(py)
                .call_method1("evaluate", (array1(py, x), array1(py, u)))?;
            v.extract::<f64>()
        })
        .unwrap_or(f64::NAN);
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let bufs = call_guarded(&self.slot, &self.obj, "derivatives", x, u, &self.shapes());
        write_col(&mut data.lx, &bufs[0]);
        write_col(&mut data.lu, &bufs[1]);
        write_mat(&mut data.lxx, &bufs[2]);
        write_mat(&mut data.lxu, &bufs[3]);
        write_mat(&mut data.luu, &bufs[4]);
    }
}

/// A stage function subclassed in Python: `evaluate(x, u) -> r` and
/// `jacobians(x, u) -> (Jx, Ju)`.
pub struct PyFunctionModel {
    obj: Py<PyAny>,
    dims: Dims,
    slot: Arc<Slot>,
}

impl PyFunctionModel {
    fn shapes(&self) -> [(&'static str, usize, Option<usize>); 2] {
        let Dims { ndx, nu, nr, .. } = self.dims;
        [("Jx", nr, Some(ndx)), ("Ju", nr, Some(nu))]
    }

    /// Wraps `obj` after one checked call of each method at the neutral state.
    pub fn new(obj: &Bound<'_, PyAny>, space: &dyn Manifold, nu: usize, nr: usize) -> PyResult<(Arc<Self>, Arc<Slot>)> {
        let dims = Dims {
            nx: space.nx(),
            ndx: space.ndx(),
            nu,
            nr,
        };
        let slot = Slot::new(class_name(obj));
        let model = Self {
            obj: obj.clone().unbind(),
            dims,
            slot: slot.clone(),
        };
        let (x, u) = (neutral(space), vec![0.0; nu]);
        call_arrays(obj, "evaluate", &x, &u, &[("r", nr, None)], &mut [vec![0.0; nr]])?;
        let shapes = model.shapes();
        call_arrays(obj, "jacobians", &x, &u, &shapes, &mut buffers(&shapes))?;
        Ok((Arc::new(model), slot))
    }
}

impl StageFunction for PyFunctionModel {
    fn nx(&self) -> usize {
        self.dims.nx
    }
    fn ndx(&self) -> usize {
        self.dims.ndx
    }
    fn nu(&self) -> usize {
        self.dims.nu
    }
    fn nr(&self) -> usize {
        self.dims.nr
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let r = call_guarded(&self.slot, &self.obj, "evaluate", x, u, &[("r", self.dims.nr, None)]);
        write_col(&mut data.value, &r[0]);
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let bufs = call_guarded(&self.slot, &self.obj, "jacobians", x, u, &self.shapes());
        write_mat(&mut data.jx, &bufs[0]);
        write_mat(&mut data.ju, &bufs[1]);
    }
}

/// An ODE subclassed in Python: `forward(x, u) -> xdot` and `jacobians(x, u) -> (Jx, Ju)`.
pub struct PyOdeModel {
    obj: Py<PyAny>,
    space: Arc<dyn Manifold>,
    nu: usize,
    slot: Arc<Slot>,
}

impl PyOdeModel {
    fn shapes(&self) -> [(&'static str, usize, Option<usize>); 2] {
        let ndx = self.space.ndx();
        [("Jx", ndx, Some(ndx)), ("Ju", ndx, Some(self.nu))]
    }

    /// Wraps `obj` after one checked call of each method at the neutral state.
    pub fn new(obj: &Bound<'_, PyAny>, space: Arc<dyn Manifold>, nu: usize) -> PyResult<(Arc<Self>, Arc<Slot>)> {
        let slot = Slot::new(class_name(obj));
        let model = Self {
            obj: obj.clone().unbind(),
            space: space.clone(),
            nu,
            slot: slot.clone(),
        };
        let (x, u) = (neutral(space.as_ref()), vec![0.0; nu]);
        let ndx = space.ndx();
        call_arrays(obj, "forward", &x, &u, &[("xdot", ndx, None)], &mut [vec![0.0; ndx]])?;
        let shapes = model.shapes();
        call_arrays(obj, "jacobians", &x, &u, &shapes, &mut buffers(&shapes))?;
        Ok((Arc::new(model), slot))
    }
}

impl Ode for PyOdeModel {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let shape = [("xdot", self.space.ndx(), None)];
        let xdot = call_guarded(&self.slot, &self.obj, "forward", x, u, &shape);
        write_col(&mut data.xdot, &xdot[0]);
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let bufs = call_guarded(&self.slot, &self.obj, "jacobians", x, u, &self.shapes());
        write_mat(&mut data.jx, &bufs[0]);
        write_mat(&mut data.ju, &bufs[1]);
    }
}
