//! Calls every benchmarked algorithm on the K = 100 samples of the criterion benchmarks,
//! each from its own non-inlined function `count_<algorithm>`, so that an instruction
//! counter attributes the work per algorithm:
//!
//! ```text
//! cargo build --release -p gharial-multibody --example count_instructions
//! valgrind --tool=callgrind --callgrind-out-file=cg.out \
//!     target/release/examples/count_instructions g1 [repetitions]
//! callgrind_annotate --inclusive=yes cg.out | grep count_
//! ```
//!
//! Instructions per call = inclusive count / (100 × repetitions).

#[path = "../benches/common/mod.rs"]
mod common;

use common::{Sample, robots, samples};
use gharial_multibody::*;
use std::hint::black_box;

macro_rules! counted {
    ($name:ident, |$model:ident, $data:ident, $x:ident| $body:expr) => {
        #[inline(never)]
        fn $name($model: &Model, $data: &mut Data, s: &[Sample], reps: usize) {
            for _ in 0..reps {
                for $x in s {
                    black_box($body);
                }
            }
        }
    };
}

counted!(count_forward_kinematics, |m, d, x| forward_kinematics(
    m, d, &x.q, &x.v, &x.a
)
.unwrap());
counted!(count_compute_joint_jacobians, |m, d, x| compute_joint_jacobians(
    m, d, &x.q
)
.unwrap());
counted!(count_rnea, |m, d, x| rnea(m, d, &x.q, &x.v, &x.a).unwrap()[0]);
counted!(count_nonlinear_effects, |m, d, x| nonlinear_effects(m, d, &x.q, &x.v)
    .unwrap()[0]);
counted!(count_crba, |m, d, x| crba(m, d, &x.q).unwrap()[(0, 0)]);
counted!(count_aba, |m, d, x| aba(m, d, &x.q, &x.v, &x.tau).unwrap()[0]);
counted!(count_compute_rnea_derivatives, |m, d, x| compute_rnea_derivatives(
    m, d, &x.q, &x.v, &x.a
)
.unwrap());
counted!(count_compute_aba_derivatives, |m, d, x| compute_aba_derivatives(
    m, d, &x.q, &x.v, &x.tau
)
.unwrap());

#[inline(never)]
fn count_constraint_dynamics(
    model: &Model,
    data: &mut Data,
    contacts: &[ContactModel],
    cd: &mut ContactData,
    x: &Sample,
) {
    constraint_dynamics(model, data, contacts, cd, &x.q, &x.v, &x.tau).unwrap();
    black_box(cd.ddq()[0]);
}

#[inline(never)]
fn count_constraint_dynamics_derivatives(
    model: &Model,
    data: &mut Data,
    contacts: &[ContactModel],
    cd: &mut ContactData,
) {
    compute_constraint_dynamics_derivatives(model, data, contacts, cd).unwrap();
    black_box(cd.ddq_dq()[(0, 0)]);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let robot = args.get(1).map(String::as_str).unwrap_or("ur5");
    let reps: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(1);
    let (_, model, contacts) = robots()
        .into_iter()
        .find(|(name, _, _)| *name == robot)
        .expect("robot: ur5, solo12 or g1");
    let s = samples(&model, 100, 1);
    let mut data = model.create_data();
    let d = &mut data;
    count_forward_kinematics(&model, d, &s, reps);
    count_compute_joint_jacobians(&model, d, &s, reps);
    count_rnea(&model, d, &s, reps);
    count_nonlinear_effects(&model, d, &s, reps);
    count_crba(&model, d, &s, reps);
    count_aba(&model, d, &s, reps);
    count_compute_rnea_derivatives(&model, d, &s, reps);
    count_compute_aba_derivatives(&model, d, &s, reps);
    if !contacts.is_empty() {
        let mut cd = ContactData::new(&model, &contacts).expect("contact data");
        for _ in 0..reps {
            for x in &s {
                count_constraint_dynamics(&model, d, &contacts, &mut cd, x);
                count_constraint_dynamics_derivatives(&model, d, &contacts, &mut cd);
            }
        }
    }
}
