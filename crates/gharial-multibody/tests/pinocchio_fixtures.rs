//! Every quantity of every Pinocchio fixture, for every sample, against this crate.
//!
//! Reads `tests/data/fixtures/pinocchio/*.json` and the same layout under every root
//! listed in `GHARIAL_FIXTURES_DIRS` (colon-separated). Each fixture's URDF is
//! `<root>/<source.urdf>`. Relative error: `max|x − ref| / max(1, max|ref|)`.

use faer::{Mat, MatRef};
use gharial_multibody::*;
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Default tolerance on the relative error.
const TOL: f64 = 1e-9;

/// Sample keys that are inputs or metadata rather than checked outputs.
const INPUT_KEYS: [&str; 5] = ["index", "q", "v", "a", "tau"];

struct Checker {
    robot: String,
    /// quantity -> (max relative error, number of comparisons, tolerance)
    stats: BTreeMap<String, (f64, usize, f64)>,
    failures: Vec<String>,
}

impl Checker {
    fn new(robot: &str) -> Self {
        Self {
            robot: robot.to_string(),
            stats: BTreeMap::new(),
            failures: Vec::new(),
        }
    }

    fn fail(&mut self, msg: String) {
        self.failures.push(format!("{}: {}", self.robot, msg));
    }

    fn record(&mut self, quantity: &str, err: f64, tol: f64, context: &str) {
        let e = self.stats.entry(quantity.to_string()).or_insert((0.0, 0, tol));
        e.0 = e.0.max(if err.is_nan() { f64::INFINITY } else { err });
        e.1 += 1;
        if err.is_nan() || err > tol {
            let msg = format!("{quantity} [{context}]: relative error {err:.3e} > {tol:.0e}");
            self.fail(msg);
        }
    }

    fn vec(&mut self, quantity: &str, got: &[f64], want: &[f64], tol: f64, context: &str) {
        if got.len() != want.len() {
            self.fail(format!(
                "{quantity} [{context}]: length {} != {}",
                got.len(),
                want.len()
            ));
            return;
        }
        self.record(quantity, rel_err(got, want), tol, context);
    }

    fn mat(&mut self, quantity: &str, got: MatRef<'_, f64>, want: &[Vec<f64>], tol: f64, context: &str) {
        if got.nrows() != want.len() || want.iter().any(|r| r.len() != got.ncols()) {
            self.fail(format!(
                "{quantity} [{context}]: shape {}x{} differs from the fixture",
                got.nrows(),
                got.ncols()
            ));
            return;
        }
        let g: Vec<f64> = (0..got.nrows())
            .flat_map(|i| (0..got.ncols()).map(move |j| got[(i, j)]))
            .collect();
        let w: Vec<f64> = want.iter().flatten().copied().collect();
        self.record(quantity, rel_err(&g, &w), tol, context);
    }

    fn se3(&mut self, quantity: &str, got: &spatial::Se3, want: &[Vec<f64>], context: &str) {
        let h = got.to_homogeneous();
        let g: Vec<f64> = h.iter().flatten().copied().collect();
        let w: Vec<f64> = want.iter().flatten().copied().collect();
        self.vec(quantity, &g, &w, TOL, context);
    }

    fn equal<T: PartialEq + std::fmt::Debug>(&mut self, quantity: &str, got: T, want: T) {
        let e = self.stats.entry(quantity.to_string()).or_insert((0.0, 0, 0.0));
        e.1 += 1;
        if got != want {
            self.fail(format!("{quantity}: {got:?} != {want:?}"));
        }
    }
}

fn rel_err(got: &[f64], want: &[f64]) -> f64 {
    let scale = want.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    let diff = got.iter().zip(want).fold(0.0f64, |m, (g, w)| {
        let d = (g - w).abs();
        if d.is_nan() { f64::INFINITY } else { m.max(d) }
    });
    diff / scale
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn vecf(v: &Value) -> Vec<f64> {
    v.as_array().map(|a| a.iter().map(f).collect()).unwrap_or_default()
}

fn matf(v: &Value) -> Vec<Vec<f64>> {
    v.as_array().map(|a| a.iter().map(vecf).collect()).unwrap_or_default()
}

fn rf_of(name: &str) -> ReferenceFrame {
    match name {
        "LOCAL" => ReferenceFrame::Local,
        "WORLD" => ReferenceFrame::World,
        "LOCAL_WORLD_ALIGNED" => ReferenceFrame::LocalWorldAligned,
        other => panic!("unknown reference frame {other}"),
    }
}

fn roots() -> Vec<PathBuf> {
    let mut roots = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")];
    if let Ok(extra) = std::env::var("GHARIAL_FIXTURES_DIRS") {
        roots.extend(extra.split(':').filter(|s| !s.is_empty()).map(PathBuf::from));
    }
    roots
}

#[test]
fn pinocchio_fixtures() {
    let mut failures = Vec::new();
    let mut nfix = 0;
    for root in roots() {
        let dir = root.join("fixtures/pinocchio");
        let mut files: Vec<PathBuf> = match std::fs::read_dir(&dir) {
            Ok(rd) => rd
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "json"))
                .collect(),
            Err(e) => {
                failures.push(format!("cannot read fixture directory {}: {e}", dir.display()));
                continue;
            }
        };
        files.sort();
        if files.is_empty() {
            failures.push(format!("no fixture in {}", dir.display()));
        }
        for file in files {
            nfix += 1;
            match check_fixture(&root, &file) {
                Ok(checker) => {
                    println!("== {} ({})", checker.robot, file.display());
                    for (q, (err, n, tol)) in &checker.stats {
                        println!("   {q:<58} n={n:<5} max_rel={err:.2e} tol={tol:.0e}");
                    }
                    failures.extend(checker.failures);
                }
                Err(e) => failures.push(format!("{}: cannot load: {e}", file.display())),
            }
        }
    }
    println!("{nfix} fixture files checked");
    if !failures.is_empty() {
        let shown: Vec<&String> = failures.iter().take(60).collect();
        panic!(
            "{} failures:\n{}",
            failures.len(),
            shown.iter().map(|s| s.as_str()).collect::<Vec<_>>().join("\n")
        );
    }
}

fn check_fixture(root: &Path, file: &Path) -> std::result::Result<Checker, String> {
    let text = std::fs::read_to_string(file).map_err(|e| e.to_string())?;
    let fx: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let robot = fx["robot"].as_str().ok_or("no robot name")?;
    let model = build_model(root, &fx["source"])?;
    let mut ck = Checker::new(robot);
    check_model(&mut ck, &model, &fx["model"]);
    let frames_used: Vec<String> = fx["frames_used"]
        .as_array()
        .map(|a| a.iter().filter_map(|x| x.as_str().map(String::from)).collect())
        .unwrap_or_default();
    for name in &frames_used {
        if model.frame_id(name).is_err() {
            ck.fail(format!("frame {name} of frames_used not in the model"));
        }
    }
    let samples = fx["samples"].as_array().ok_or("no samples")?;
    if samples.is_empty() {
        return Err("no samples".into());
    }
    for s in samples {
        check_sample(&mut ck, &model, s);
    }
    Ok(ck)
}

/// Builds the model as the fixture's `source` says (every field of the fixtures README):
/// the URDF `urdf` (relative to the fixture root) whose SHA-256 must be `urdf_sha256`,
/// the root joint `root_joint` with the matching `build_call`, the mimic treatment
/// `mimic` (only `false`, Pinocchio's default, is reproduced), and the SRDF `srdf`
/// (or null): its reference configurations always, its rotor parameters (armature)
/// only when `armature_from_srdf` is true.
fn build_model(root: &Path, source: &Value) -> std::result::Result<Model, String> {
    let field = |key: &str| {
        let v = &source[key];
        if v.is_null() && !matches!(key, "srdf") {
            Err(format!("source.{key} missing"))
        } else {
            Ok(v)
        }
    };
    let urdf = root.join(field("urdf")?.as_str().ok_or("source.urdf is not a string")?);
    let bytes = std::fs::read(&urdf).map_err(|e| format!("{}: {e}", urdf.display()))?;
    let sha: String = Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect();
    let want_sha = field("urdf_sha256")?
        .as_str()
        .ok_or("source.urdf_sha256 is not a string")?;
    if sha != want_sha {
        return Err(format!(
            "{}: sha256 {sha} differs from the fixture's {want_sha} (the fixture was made from another file)",
            urdf.display()
        ));
    }
    let (rootj, call) = match field("root_joint")?.as_str() {
        Some("fixed") => (RootJoint::Fixed, "pin.buildModelFromUrdf(urdf)"),
        Some("JointModelFreeFlyer") => (
            RootJoint::FreeFlyer,
            "pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())",
        ),
        other => return Err(format!("unknown source.root_joint {other:?}")),
    };
    if field("build_call")?.as_str() != Some(call) {
        return Err(format!(
            "source.build_call {} is not the call `{call}` that this test reproduces",
            source["build_call"]
        ));
    }
    let options = match field("mimic")?.as_bool() {
        Some(false) => UrdfOptions {
            mimic: MimicPolicy::Independent,
        },
        other => {
            return Err(format!(
                "source.mimic = {other:?}: only false (independent mimic joints) is supported"
            ));
        }
    };
    let armature_from_srdf = field("armature_from_srdf")?
        .as_bool()
        .ok_or("source.armature_from_srdf is not a boolean")?;
    let mut model = Model::from_urdf_file_with(&urdf, rootj, &options).map_err(|e| e.to_string())?;
    match source["srdf"].as_str() {
        Some(srdf) => {
            let what = SrdfOptions {
                reference_configurations: true,
                rotor_parameters: armature_from_srdf,
            };
            model
                .load_srdf_file_with(root.join(srdf), &what)
                .map_err(|e| e.to_string())?;
        }
        None if armature_from_srdf => return Err("source.armature_from_srdf is true but source.srdf is null".into()),
        None => {}
    }
    Ok(model)
}

fn check_model(ck: &mut Checker, model: &Model, m: &Value) {
    ck.equal("model.nq", model.nq() as i64, m["nq"].as_i64().unwrap_or(-1));
    ck.equal("model.nv", model.nv() as i64, m["nv"].as_i64().unwrap_or(-1));
    ck.equal(
        "model.njoints",
        model.njoints() as i64,
        m["njoints"].as_i64().unwrap_or(-1),
    );
    ck.equal(
        "model.nbodies",
        model.njoints() as i64,
        m["nbodies"].as_i64().unwrap_or(-1),
    );
    ck.equal(
        "model.nframes",
        model.nframes() as i64,
        m["nframes"].as_i64().unwrap_or(-1),
    );
    ck.equal("model.name", model.name.as_str(), m["name"].as_str().unwrap_or(""));
    ck.vec(
        "model.gravity",
        &model.gravity.to_array(),
        &vecf(&m["gravity"]),
        TOL,
        "",
    );
    let joints = m["joints"].as_array().cloned().unwrap_or_default();
    if joints.len() != model.njoints() {
        ck.fail(format!(
            "model.joints: {} in the fixture, {} in the model",
            joints.len(),
            model.njoints()
        ));
    }
    for (i, j) in joints.iter().enumerate().take(model.njoints()) {
        let jm = model.joints()[i];
        let ctx = format!("joint {i}");
        ck.equal(
            "model.joints.name",
            model.joint_names()[i].as_str(),
            j["name"].as_str().unwrap_or(""),
        );
        ck.equal(
            "model.joints.type",
            jm.kind.shortname(),
            j["type"].as_str().unwrap_or(""),
        );
        ck.equal(
            "model.joints.parent",
            model.parents()[i] as i64,
            j["parent"].as_i64().unwrap_or(-2),
        );
        if i > 0 {
            ck.equal("model.joints.idx_q", jm.idx_q as i64, j["idx_q"].as_i64().unwrap_or(-2));
            ck.equal("model.joints.idx_v", jm.idx_v as i64, j["idx_v"].as_i64().unwrap_or(-2));
        }
        ck.equal("model.joints.nq", jm.nq as i64, j["nq"].as_i64().unwrap_or(-2));
        ck.equal("model.joints.nv", jm.nv as i64, j["nv"].as_i64().unwrap_or(-2));
        match (jm.kind.unaligned_axis(), j["axis"].is_null()) {
            (None, true) => ck.equal("model.joints.axis", true, true),
            (Some(a), false) => ck.vec("model.joints.axis", a.as_slice(), &vecf(&j["axis"]), TOL, &ctx),
            _ => ck.fail(format!("model.joints.axis [{ctx}]: aligned/unaligned mismatch")),
        }
        ck.se3(
            "model.joints.placement",
            &model.joint_placements()[i],
            &matf(&j["placement"]),
            &ctx,
        );
        let y = &model.inertias()[i];
        let yi = &j["inertia"];
        ck.vec("model.joints.inertia.mass", &[y.mass], &[f(&yi["mass"])], TOL, &ctx);
        ck.vec(
            "model.joints.inertia.lever",
            y.lever().as_slice(),
            &vecf(&yi["lever"]),
            TOL,
            &ctx,
        );
        let ic = y.inertia_com();
        let icv: Vec<f64> = (0..3).flat_map(|r| (0..3).map(move |c| ic[(r, c)])).collect();
        ck.vec(
            "model.joints.inertia.inertia",
            &icv,
            &matf(&yi["inertia"]).concat(),
            TOL,
            &ctx,
        );
        ck.vec(
            "model.joints.inertia.matrix6",
            &y.matrix6().concat(),
            &matf(&yi["matrix6"]).concat(),
            TOL,
            &ctx,
        );
    }
    let frames = m["frames"].as_array().cloned().unwrap_or_default();
    if frames.len() != model.nframes() {
        ck.fail(format!(
            "model.frames: {} in the fixture, {} in the model",
            frames.len(),
            model.nframes()
        ));
    }
    for (k, fr) in frames.iter().enumerate().take(model.nframes()) {
        let mf = &model.frames()[k];
        ck.equal("model.frames.name", mf.name.as_str(), fr["name"].as_str().unwrap_or(""));
        ck.equal("model.frames.type", mf.kind.name(), fr["type"].as_str().unwrap_or(""));
        ck.equal(
            "model.frames.parent_joint",
            mf.parent_joint as i64,
            fr["parent_joint"].as_i64().unwrap_or(-1),
        );
        ck.equal(
            "model.frames.parent_frame",
            mf.parent_frame as i64,
            fr["parent_frame"].as_i64().unwrap_or(-1),
        );
        ck.se3(
            "model.frames.placement",
            &mf.placement,
            &matf(&fr["placement"]),
            &format!("frame {k}"),
        );
    }
    let lists: [(&str, &[f64]); 10] = [
        ("lower_position_limit", &model.lower_position_limit),
        ("upper_position_limit", &model.upper_position_limit),
        ("velocity_limit", &model.velocity_limit),
        ("effort_limit", &model.effort_limit),
        ("armature", &model.armature),
        ("damping", &model.damping),
        ("friction", &model.friction),
        ("rotor_inertia", &model.rotor_inertia),
        ("rotor_gear_ratio", &model.rotor_gear_ratio),
        ("neutral", &neutral(model)),
    ];
    for (name, got) in lists {
        ck.vec(&format!("model.{name}"), got, &vecf(&m[name]), TOL, "");
    }
    if let Some(cfgs) = m["srdf_reference_configurations"].as_object() {
        for (name, q) in cfgs {
            match model.reference_configuration(name) {
                Ok(got) => ck.vec("model.srdf_reference_configurations", got, &vecf(q), TOL, name),
                Err(e) => ck.fail(format!("srdf reference configuration {name}: {e}")),
            }
        }
    }
}

/// Compares a configuration, quaternion blocks up to sign.
fn config_err(model: &Model, got: &[f64], want: &[f64]) -> f64 {
    let mut g = got.to_vec();
    for jm in model.joints() {
        let r = match jm.kind {
            JointType::FreeFlyer => jm.idx_q + 3..jm.idx_q + 7,
            JointType::Spherical => jm.idx_q..jm.idx_q + 4,
            _ => continue,
        };
        let same: f64 = r.clone().map(|k| (g[k] - want[k]).abs()).fold(0.0, f64::max);
        let flip: f64 = r.clone().map(|k| (g[k] + want[k]).abs()).fold(0.0, f64::max);
        if flip < same {
            r.for_each(|k| g[k] = -g[k]);
        }
    }
    rel_err(&g, want)
}

fn check_sample(ck: &mut Checker, model: &Model, s: &Value) {
    let idx = s["index"].as_i64().unwrap_or(-1);
    let ctx = format!("sample {idx}");
    let (q, v, a, tau) = (vecf(&s["q"]), vecf(&s["v"]), vecf(&s["a"]), vecf(&s["tau"]));
    let nv = model.nv();
    let mut handled: Vec<&str> = INPUT_KEYS.to_vec();
    let mut data = model.create_data();

    // Kinematics.
    forward_kinematics(model, &mut data, &q, &v, &a).expect("forward_kinematics");
    update_frame_placements(model, &mut data).expect("frames");
    handled.extend(["oMi", "joint_velocity_local", "joint_acceleration_local", "oMf"]);
    for (i, m) in matf_list(&s["oMi"]).iter().enumerate() {
        ck.se3("oMi", data.joint_placement(i), m, &ctx);
    }
    for (i, w) in s["joint_velocity_local"].as_array().into_iter().flatten().enumerate() {
        ck.vec(
            "joint_velocity_local",
            &joint_velocity(&data, i, ReferenceFrame::Local).expect("v").to_array(),
            &vecf(w),
            TOL,
            &ctx,
        );
    }
    for (i, w) in s["joint_acceleration_local"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
    {
        ck.vec(
            "joint_acceleration_local",
            &joint_acceleration(&data, i, ReferenceFrame::Local)
                .expect("a")
                .to_array(),
            &vecf(w),
            TOL,
            &ctx,
        );
    }
    for (k, m) in matf_list(&s["oMf"]).iter().enumerate() {
        ck.se3("oMf", data.frame_placement(k), m, &ctx);
    }
    handled.extend([
        "frame_velocity",
        "frame_acceleration",
        "frame_classical_acceleration",
        "frame_jacobian",
    ]);
    for (key, func) in [
        (
            "frame_velocity",
            frame_velocity as fn(&Model, &Data, usize, ReferenceFrame) -> gharial_multibody::Result<spatial::Motion>,
        ),
        ("frame_acceleration", frame_acceleration),
        ("frame_classical_acceleration", frame_classical_acceleration),
    ] {
        for (fname, refs) in s[key].as_object().into_iter().flatten() {
            let fid = model.frame_id(fname).expect("frame");
            for (rname, w) in refs.as_object().into_iter().flatten() {
                let got = func(model, &data, fid, rf_of(rname)).expect(key).to_array();
                ck.vec(
                    &format!("{key}[{rname}]"),
                    &got,
                    &vecf(w),
                    TOL,
                    &format!("{ctx} {fname}"),
                );
            }
        }
    }
    let mut jd = model.create_data();
    compute_joint_jacobians(model, &mut jd, &q).expect("jacobians");
    let mut jac = Mat::<f64>::zeros(6, nv);
    for (fname, refs) in s["frame_jacobian"].as_object().into_iter().flatten() {
        let fid = model.frame_id(fname).expect("frame");
        for (rname, w) in refs.as_object().into_iter().flatten() {
            frame_jacobian(model, &jd, fid, rf_of(rname), jac.as_mut()).expect("frame_jacobian");
            ck.mat(
                &format!("frame_jacobian[{rname}]"),
                jac.as_ref(),
                &matf(w),
                TOL,
                &format!("{ctx} {fname}"),
            );
        }
    }

    // Dynamics, each with a fresh Data.
    handled.extend([
        "rnea",
        "joint_force_local",
        "nle",
        "generalized_gravity",
        "crba_M",
        "crba_raw_max_asymmetry",
        "aba",
    ]);
    let mut d = model.create_data();
    let got = rnea(model, &mut d, &q, &v, &a).expect("rnea").to_vec();
    ck.vec("rnea", &got, &vecf(&s["rnea"]), TOL, &ctx);
    for (i, w) in s["joint_force_local"].as_array().into_iter().flatten().enumerate() {
        if i > 0 {
            ck.vec(
                "joint_force_local",
                &d.joint_force_local(i).to_array(),
                &vecf(w),
                TOL,
                &ctx,
            );
        }
    }
    let mut d = model.create_data();
    let got = nonlinear_effects(model, &mut d, &q, &v).expect("nle").to_vec();
    ck.vec("nle", &got, &vecf(&s["nle"]), TOL, &ctx);
    let mut d = model.create_data();
    let got = generalized_gravity(model, &mut d, &q).expect("gravity").to_vec();
    ck.vec("generalized_gravity", &got, &vecf(&s["generalized_gravity"]), TOL, &ctx);
    let mut d = model.create_data();
    let m = crba(model, &mut d, &q).expect("crba");
    ck.mat("crba_M", m, &matf(&s["crba_M"]), TOL, &ctx);
    let asym = (0..nv)
        .flat_map(|i| (0..nv).map(move |j| (i, j)))
        .fold(0.0f64, |x, (i, j)| x.max((m[(i, j)] - m[(j, i)]).abs()));
    ck.vec(
        "crba_raw_max_asymmetry",
        &[asym],
        &[f(&s["crba_raw_max_asymmetry"])],
        0.0,
        &ctx,
    );
    let mut d = model.create_data();
    let got = aba(model, &mut d, &q, &v, &tau).expect("aba").to_vec();
    ck.vec("aba", &got, &vecf(&s["aba"]), TOL, &ctx);

    // Derivatives.
    handled.extend(["rnea_derivatives", "aba_derivatives"]);
    let mut d = model.create_data();
    compute_rnea_derivatives(model, &mut d, &q, &v, &a).expect("rnea derivatives");
    let rd = &s["rnea_derivatives"];
    ck.mat(
        "rnea_derivatives.dtau_dq",
        d.dtau_dq(),
        &matf(&rd["dtau_dq"]),
        TOL,
        &ctx,
    );
    ck.mat(
        "rnea_derivatives.dtau_dv",
        d.dtau_dv(),
        &matf(&rd["dtau_dv"]),
        TOL,
        &ctx,
    );
    ck.mat(
        "rnea_derivatives.dtau_da",
        d.mass_matrix(),
        &matf(&rd["dtau_da"]),
        TOL,
        &ctx,
    );
    let mut d = model.create_data();
    compute_aba_derivatives(model, &mut d, &q, &v, &tau).expect("aba derivatives");
    let ad = &s["aba_derivatives"];
    ck.mat("aba_derivatives.ddq_dq", d.ddq_dq(), &matf(&ad["ddq_dq"]), TOL, &ctx);
    ck.mat("aba_derivatives.ddq_dv", d.ddq_dv(), &matf(&ad["ddq_dv"]), TOL, &ctx);
    ck.mat("aba_derivatives.ddq_dtau", d.minv(), &matf(&ad["ddq_dtau"]), TOL, &ctx);

    // Centre of mass.
    handled.push("com");
    let c = &s["com"];
    let mut d = model.create_data();
    center_of_mass(model, &mut d, &q, &v, &a).expect("com");
    ck.vec("com.total_mass", &[d.total_mass()], &[f(&c["total_mass"])], TOL, &ctx);
    ck.vec("com.com", d.com().as_slice(), &vecf(&c["com"]), TOL, &ctx);
    ck.vec("com.vcom", d.vcom().as_slice(), &vecf(&c["vcom"]), TOL, &ctx);
    ck.vec("com.acom", d.acom().as_slice(), &vecf(&c["acom"]), TOL, &ctx);
    let jc = jacobian_center_of_mass(model, &mut d, &q).expect("jcom");
    ck.mat("com.jacobian", jc, &matf(&c["jacobian"]), TOL, &ctx);

    // Kinematic derivatives.
    handled.push("kinematics_derivatives");
    let mut d = model.create_data();
    compute_forward_kinematics_derivatives(model, &mut d, &q, &v, &a).expect("kinematics derivatives");
    let mut mats: Vec<Mat<f64>> = (0..5).map(|_| Mat::zeros(6, nv)).collect();
    for (fname, refs) in s["kinematics_derivatives"].as_object().into_iter().flatten() {
        let fid = model.frame_id(fname).expect("frame");
        for (rname, w) in refs.as_object().into_iter().flatten() {
            let rf = rf_of(rname);
            let [m0, m1, m2, m3, m4] = &mut mats[..] else {
                unreachable!()
            };
            frame_velocity_derivatives(model, &d, fid, rf, m0.as_mut(), m1.as_mut()).expect("dv");
            frame_acceleration_derivatives(model, &d, fid, rf, m0.as_mut(), m2.as_mut(), m3.as_mut(), m4.as_mut())
                .expect("da");
            let c = format!("{ctx} {fname}");
            ck.mat(
                &format!("kinematics_derivatives[{rname}].dv_dq"),
                m0.as_ref(),
                &matf(&w["dv_dq"]),
                TOL,
                &c,
            );
            ck.mat(
                &format!("kinematics_derivatives[{rname}].dv_dv"),
                m1.as_ref(),
                &matf(&w["dv_dv"]),
                TOL,
                &c,
            );
            ck.mat(
                &format!("kinematics_derivatives[{rname}].da_dq"),
                m2.as_ref(),
                &matf(&w["da_dq"]),
                TOL,
                &c,
            );
            ck.mat(
                &format!("kinematics_derivatives[{rname}].da_dv"),
                m3.as_ref(),
                &matf(&w["da_dv"]),
                TOL,
                &c,
            );
            ck.mat(
                &format!("kinematics_derivatives[{rname}].da_da"),
                m4.as_ref(),
                &matf(&w["da_da"]),
                TOL,
                &c,
            );
        }
    }

    // Lie-group operations.
    handled.extend(["integrate", "difference"]);
    let it = &s["integrate"];
    let (iq, iv) = (vecf(&it["q"]), vecf(&it["v"]));
    let mut out = vec![0.0; model.nq()];
    integrate(model, &iq, &iv, &mut out).expect("integrate");
    let want = vecf(&it["result"]);
    ck.record("integrate.result", config_err(model, &out, &want), TOL, &ctx);
    let mut jm = Mat::<f64>::zeros(nv, nv);
    dintegrate(model, &iq, &iv, ArgumentPosition::Arg0, jm.as_mut()).expect("dintegrate");
    ck.mat("integrate.d_dq", jm.as_ref(), &matf(&it["d_dq"]), TOL, &ctx);
    dintegrate(model, &iq, &iv, ArgumentPosition::Arg1, jm.as_mut()).expect("dintegrate");
    ck.mat("integrate.d_dv", jm.as_ref(), &matf(&it["d_dv"]), TOL, &ctx);
    let df = &s["difference"];
    let (q0, q1) = (vecf(&df["q0"]), vecf(&df["q1"]));
    let mut dv = vec![0.0; nv];
    difference(model, &q0, &q1, &mut dv).expect("difference");
    ck.vec("difference.result", &dv, &vecf(&df["result"]), TOL, &ctx);
    ddifference(model, &q0, &q1, ArgumentPosition::Arg0, jm.as_mut()).expect("ddifference");
    ck.mat("difference.d_dq0", jm.as_ref(), &matf(&df["d_dq0"]), TOL, &ctx);
    ddifference(model, &q0, &q1, ArgumentPosition::Arg1, jm.as_mut()).expect("ddifference");
    ck.mat("difference.d_dq1", jm.as_ref(), &matf(&df["d_dq1"]), TOL, &ctx);

    // Constrained dynamics.
    handled.push("constraint_dynamics");
    for setup in s["constraint_dynamics"].as_array().into_iter().flatten() {
        check_contact_setup(ck, model, s, setup, &ctx, &q, &v, &tau);
    }

    if let Some(obj) = s.as_object() {
        for key in obj.keys() {
            if !handled.contains(&key.as_str()) {
                ck.fail(format!("quantity `{key}` of the fixture is not checked"));
            }
        }
    }
}

fn matf_list(v: &Value) -> Vec<Vec<Vec<f64>>> {
    v.as_array().map(|a| a.iter().map(matf).collect()).unwrap_or_default()
}

#[allow(clippy::too_many_arguments)]
fn check_contact_setup(
    ck: &mut Checker,
    model: &Model,
    _s: &Value,
    setup: &Value,
    ctx: &str,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) {
    let name = setup["name"].as_str().unwrap_or("?");
    let ctx = format!("{ctx} {name}");
    let kind = match setup["type"].as_str() {
        Some("CONTACT_3D") => ContactType::Contact3D,
        Some("CONTACT_6D") => ContactType::Contact6D,
        other => {
            ck.fail(format!("constraint_dynamics [{ctx}]: unknown type {other:?}"));
            return;
        }
    };
    let rf = rf_of(setup["reference_frame"].as_str().unwrap_or(""));
    let (kp, kd) = (f(&setup["baumgarte"]["Kp"]), f(&setup["baumgarte"]["Kd"]));
    let mu = f(&setup["prox_settings"]["mu"]);
    if mu != 0.0 {
        ck.fail(format!(
            "constraint_dynamics [{ctx}]: proximal mu = {mu} is not supported (exact KKT only)"
        ));
    }
    let frames: Vec<&str> = setup["frames"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|x| x.as_str())
        .collect();
    let j1 = setup["joint1_id"].as_array().cloned().unwrap_or_default();
    let j1p = setup["joint1_placement"].as_array().cloned().unwrap_or_default();
    let j2 = setup["joint2_id"].as_array().cloned().unwrap_or_default();
    let mut contacts = Vec::new();
    for (k, fname) in frames.iter().enumerate() {
        let fid = model.frame_id(fname).expect("contact frame");
        let mut c = ContactModel::from_frame(model, kind, fid, rf).expect("contact model");
        c.kp = kp;
        c.kd = kd;
        ck.equal(
            "constraint_dynamics.joint1_id",
            c.joint as i64,
            j1.get(k).and_then(|x| x.as_i64()).unwrap_or(-1),
        );
        ck.se3(
            "constraint_dynamics.joint1_placement",
            &c.placement,
            &matf(j1p.get(k).unwrap_or(&Value::Null)),
            &ctx,
        );
        ck.equal(
            "constraint_dynamics.joint2_id",
            0i64,
            j2.get(k).and_then(|x| x.as_i64()).unwrap_or(-1),
        );
        contacts.push(c);
    }
    // The Delassus matrix has condition numbers up to 5e4 (g1); the measured errors stay
    // near 1e-12, so the default tolerance holds here too.
    let cond = f(&setup["delassus_condition_number"]);
    ck.record(
        "constraint_dynamics.delassus_condition_number (finite)",
        if cond.is_finite() { 0.0 } else { 1.0 },
        0.0,
        &ctx,
    );
    let tol = TOL;
    let mut data = model.create_data();
    let mut cdata = ContactData::new(model, &contacts).expect("contact data");
    constraint_dynamics(model, &mut data, &contacts, &mut cdata, q, v, tau).expect("constraint dynamics");
    ck.vec("constraint_dynamics.ddq", cdata.ddq(), &vecf(&setup["ddq"]), tol, &ctx);
    ck.vec(
        "constraint_dynamics.lambda",
        cdata.lambda(),
        &vecf(&setup["lambda"]),
        tol,
        &ctx,
    );
    let per: Vec<Vec<f64>> = matf(&setup["contact_force_per_constraint"]);
    for (k, w) in per.iter().enumerate() {
        let got = cdata.contact_force(&contacts, k).to_array();
        ck.vec("constraint_dynamics.contact_force_per_constraint", &got, w, tol, &ctx);
    }
    ck.mat(
        "constraint_dynamics.constraint_jacobian",
        cdata.constraint_jacobian(),
        &matf(&setup["constraint_jacobian"]),
        TOL,
        &ctx,
    );
    compute_constraint_dynamics_derivatives(model, &mut data, &contacts, &mut cdata).expect("derivatives");
    let dd = &setup["derivatives"];
    ck.mat(
        "constraint_dynamics.derivatives.ddq_dq",
        cdata.ddq_dq(),
        &matf(&dd["ddq_dq"]),
        tol,
        &ctx,
    );
    ck.mat(
        "constraint_dynamics.derivatives.ddq_dv",
        cdata.ddq_dv(),
        &matf(&dd["ddq_dv"]),
        tol,
        &ctx,
    );
    ck.mat(
        "constraint_dynamics.derivatives.ddq_dtau",
        cdata.ddq_dtau(),
        &matf(&dd["ddq_dtau"]),
        tol,
        &ctx,
    );
    ck.mat(
        "constraint_dynamics.derivatives.dlambda_dq",
        cdata.dlambda_dq(),
        &matf(&dd["dlambda_dq"]),
        tol,
        &ctx,
    );
    ck.mat(
        "constraint_dynamics.derivatives.dlambda_dv",
        cdata.dlambda_dv(),
        &matf(&dd["dlambda_dv"]),
        tol,
        &ctx,
    );
    ck.mat(
        "constraint_dynamics.derivatives.dlambda_dtau",
        cdata.dlambda_dtau(),
        &matf(&dd["dlambda_dtau"]),
        tol,
        &ctx,
    );
    for key in setup.as_object().into_iter().flatten().map(|(k, _)| k.as_str()) {
        let known = [
            "name",
            "type",
            "frames",
            "reference_frame",
            "baumgarte",
            "joint1_id",
            "joint1_placement",
            "joint2_id",
            "joint2_placement",
            "prox_settings",
            "ddq",
            "lambda",
            "contact_force_per_constraint",
            "constraint_jacobian",
            "delassus_condition_number",
            "derivatives",
        ];
        if !known.contains(&key) {
            ck.fail(format!("constraint_dynamics quantity `{key}` is not checked"));
        }
    }
    for w in setup["joint2_placement"].as_array().into_iter().flatten() {
        ck.se3(
            "constraint_dynamics.joint2_placement",
            &spatial::Se3::identity(),
            &matf(w),
            &ctx,
        );
    }
}

/// `build_model` honours every field of `source`: the SHA-256 of the URDF, the build
/// call, `mimic`, and rotor parameters read from the SRDF only with `armature_from_srdf`.
#[test]
fn fixture_sources_are_honoured() {
    let root = std::env::temp_dir().join(format!("gharial-fixture-source-{}", std::process::id()));
    std::fs::create_dir_all(root.join("robots")).unwrap();
    let urdf = std::fs::read(roots()[0].join("robots/double_pendulum.urdf")).unwrap();
    std::fs::write(root.join("robots/p.urdf"), &urdf).unwrap();
    std::fs::write(
        root.join("robots/p.srdf"),
        r#"<robot name="p"><group_state name="up" group="all"><joint name="joint1" value="0.5"/></group_state>
        <rotor_params><joint name="joint1" mass="0.01" gear_ratio="10"/><joint name="gone" mass="1" gear_ratio="1"/></rotor_params></robot>"#,
    )
    .unwrap();
    let sha: String = Sha256::digest(&urdf).iter().map(|b| format!("{b:02x}")).collect();
    let source = |armature: bool| {
        serde_json::json!({
            "urdf": "robots/p.urdf", "urdf_sha256": sha, "srdf": "robots/p.srdf", "root_joint": "fixed",
            "build_call": "pin.buildModelFromUrdf(urdf)", "mimic": false, "armature_from_srdf": armature
        })
    };
    let m = build_model(&root, &source(false)).unwrap();
    assert_eq!(m.reference_configuration("up").unwrap()[0], 0.5);
    assert_eq!(
        (m.armature[0], m.rotor_inertia[0], m.rotor_gear_ratio[0]),
        (0.0, 0.0, 1.0)
    );
    let m = build_model(&root, &source(true)).unwrap();
    assert_eq!((m.rotor_inertia[0], m.rotor_gear_ratio[0]), (0.01, 10.0));
    assert!((m.armature[0] - 1.0).abs() < 1e-15);
    let broken = |key: &str, value: Value| {
        let mut s = source(false);
        s[key] = value;
        build_model(&root, &s).unwrap_err()
    };
    assert!(broken("urdf_sha256", Value::from("00")).contains("sha256"));
    assert!(broken("build_call", Value::from("pin.buildModelFromUrdf(urdf, mimic=True)")).contains("build_call"));
    assert!(broken("root_joint", Value::from("JointModelFreeFlyer")).contains("build_call"));
    assert!(broken("mimic", Value::from(true)).contains("mimic"));
    assert!(broken("armature_from_srdf", Value::Null).contains("armature_from_srdf"));
    let mut s = source(true);
    s["srdf"] = Value::Null;
    assert!(build_model(&root, &s).unwrap_err().contains("srdf"));
    std::fs::remove_dir_all(&root).unwrap();
}
