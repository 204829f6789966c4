//! No algorithm allocates once `Data` (and `ContactData`) exist: a counting global
//! allocator records every allocation made while the algorithms run.
#![allow(unsafe_code)]

use faer::Mat;
use gharial_multibody::*;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::SeqCst) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::SeqCst) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn count<R>(what: &str, f: impl FnOnce() -> R) -> R {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    let r = f();
    COUNTING.store(false, Ordering::SeqCst);
    let n = ALLOCATIONS.load(Ordering::SeqCst);
    println!("{what:<45} {n} allocations");
    assert_eq!(n, 0, "{what} allocated {n} times");
    r
}

#[test]
fn algorithms_do_not_allocate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/robots");
    for (file, root, feet, kind) in [
        (
            "solo12.urdf",
            RootJoint::FreeFlyer,
            vec!["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
            ContactType::Contact3D,
        ),
        (
            "g1_29dof_rev_1_0.urdf",
            RootJoint::FreeFlyer,
            vec!["left_ankle_roll_link", "right_ankle_roll_link"],
            ContactType::Contact6D,
        ),
        (
            "double_pendulum_continuous.urdf",
            RootJoint::Fixed,
            vec![],
            ContactType::Contact3D,
        ),
    ] {
        let model = Model::from_urdf_file(dir.join(file), root).unwrap();
        let (nq, nv) = (model.nq(), model.nv());
        let mut rng = SmallRng::seed_from_u64(3);
        let lo = vec![-1.0; nq];
        let hi = vec![1.0; nq];
        let q = random_configuration(&model, &mut rng, &lo, &hi).unwrap();
        let q1 = random_configuration(&model, &mut rng, &lo, &hi).unwrap();
        let v: Vec<f64> = (0..nv).map(|k| (k as f64 * 0.37).sin()).collect();
        let a: Vec<f64> = (0..nv).map(|k| (k as f64 * 0.73).cos()).collect();
        let contacts: Vec<ContactModel> = feet
            .iter()
            .map(|f| {
                ContactModel::from_frame(
                    &model,
                    kind,
                    model.frame_id(f).unwrap(),
                    ReferenceFrame::LocalWorldAligned,
                )
                .unwrap()
            })
            .collect();
        let mut data = model.create_data();
        let mut cdata = ContactData::new(&model, &contacts).unwrap();
        let mut out6 = Mat::<f64>::zeros(6, nv);
        let (mut m1, mut m2, mut m3) = (
            Mat::<f64>::zeros(6, nv),
            Mat::<f64>::zeros(6, nv),
            Mat::<f64>::zeros(6, nv),
        );
        let mut jnv = Mat::<f64>::zeros(nv, nv);
        let mut qout = vec![0.0; nq];
        let mut vout = vec![0.0; nv];
        let frame = model.nframes() - 1;
        println!("== {file}");
        count("forward_kinematics", || {
            forward_kinematics(&model, &mut data, &q, &v, &a).unwrap()
        });
        count("update_frame_placements", || {
            update_frame_placements(&model, &mut data).unwrap()
        });
        count("frame velocity/accelerations", || {
            for rf in [
                ReferenceFrame::Local,
                ReferenceFrame::World,
                ReferenceFrame::LocalWorldAligned,
            ] {
                frame_velocity(&model, &data, frame, rf).unwrap();
                frame_acceleration(&model, &data, frame, rf).unwrap();
                frame_classical_acceleration(&model, &data, frame, rf).unwrap();
            }
        });
        count("compute_joint_jacobians + frame_jacobian", || {
            compute_joint_jacobians(&model, &mut data, &q).unwrap();
            frame_jacobian(&model, &data, frame, ReferenceFrame::Local, out6.as_mut()).unwrap();
            joint_jacobian(&model, &data, 1, ReferenceFrame::World, out6.as_mut()).unwrap();
        });
        count("rnea", || {
            rnea(&model, &mut data, &q, &v, &a).unwrap();
        });
        count("nonlinear_effects", || {
            nonlinear_effects(&model, &mut data, &q, &v).unwrap();
        });
        count("generalized_gravity", || {
            generalized_gravity(&model, &mut data, &q).unwrap();
        });
        count("crba", || {
            crba(&model, &mut data, &q).unwrap();
        });
        count("aba", || {
            aba(&model, &mut data, &q, &v, &a).unwrap();
        });
        count("compute_minverse", || {
            compute_minverse(&model, &mut data, &q).unwrap();
        });
        count("center_of_mass + jacobian", || {
            center_of_mass(&model, &mut data, &q, &v, &a).unwrap();
            jacobian_center_of_mass(&model, &mut data, &q).unwrap();
        });
        count("kinematics derivatives", || {
            compute_forward_kinematics_derivatives(&model, &mut data, &q, &v, &a).unwrap();
            frame_velocity_derivatives(
                &model,
                &data,
                frame,
                ReferenceFrame::LocalWorldAligned,
                m1.as_mut(),
                m2.as_mut(),
            )
            .unwrap();
            frame_acceleration_derivatives(
                &model,
                &data,
                frame,
                ReferenceFrame::Local,
                m1.as_mut(),
                m2.as_mut(),
                m3.as_mut(),
                out6.as_mut(),
            )
            .unwrap();
        });
        count("compute_rnea_derivatives", || {
            compute_rnea_derivatives(&model, &mut data, &q, &v, &a).unwrap()
        });
        count("compute_aba_derivatives", || {
            compute_aba_derivatives(&model, &mut data, &q, &v, &a).unwrap()
        });
        count("constraint_dynamics", || {
            constraint_dynamics(&model, &mut data, &contacts, &mut cdata, &q, &v, &a).unwrap()
        });
        count("compute_constraint_dynamics_derivatives", || {
            compute_constraint_dynamics_derivatives(&model, &mut data, &contacts, &mut cdata).unwrap()
        });
        count("integrate / difference and Jacobians", || {
            integrate(&model, &q, &v, &mut qout).unwrap();
            difference(&model, &q, &q1, &mut vout).unwrap();
            dintegrate(&model, &q, &v, ArgumentPosition::Arg0, jnv.as_mut()).unwrap();
            dintegrate(&model, &q, &v, ArgumentPosition::Arg1, jnv.as_mut()).unwrap();
            ddifference(&model, &q, &q1, ArgumentPosition::Arg0, jnv.as_mut()).unwrap();
            ddifference(&model, &q, &q1, ArgumentPosition::Arg1, jnv.as_mut()).unwrap();
        });
    }
}
