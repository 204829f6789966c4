//! Pictures of the catalogue's problems without a robot model, for the viewer: the
//! pendulum, the cart-pole, the acrobot and the kinematic car, drawn from their states
//! (layouts and lengths as their modules in `gharial-problems` document them).

use gharial_viz::viewer::{Pose, Scene, Shape};

/// A rod (capsule) from `a` to `b` in every frame.
fn rod(scene: &mut Scene, name: &str, ends: impl Iterator<Item = ([f64; 3], [f64; 3])>, radius: f64) {
    let (poses, lengths): (Vec<Pose>, Vec<f64>) = ends.map(|(a, b)| Pose::between(a, b)).unzip();
    let length = lengths.first().copied().unwrap_or(0.0);
    scene.add_body(name, Shape::Capsule { radius, length }, poses);
}

/// A sphere at `p` in every frame.
fn ball(scene: &mut Scene, name: &str, ps: impl Iterator<Item = [f64; 3]>, radius: f64) {
    scene.add_body(name, Shape::Sphere { radius }, ps.map(Pose::at).collect());
}

/// The angle of `(cos θ, sin θ)`.
fn angle(c: f64, s: f64) -> f64 {
    s.atan2(c)
}

/// A point `(0, y, z)` turned by `phi` about the x axis (`θ = 0` upright).
fn turned(phi: f64, y: f64, z: f64) -> [f64; 3] {
    [0.0, y * phi.cos() - z * phi.sin(), y * phi.sin() + z * phi.cos()]
}

/// Adds the sketch of `problem` along `xs` to `scene`; `false` for problems without one.
pub fn sketch(problem: &str, xs: &[Vec<f64>], scene: &mut Scene) -> bool {
    match problem {
        // x = ((cos θ, sin θ), θ̇), l = 1, the tip at (-l sin θ, l cos θ).
        "pendulum" => {
            let tip = |x: &Vec<f64>| turned(angle(x[0], x[1]), 0.0, 1.0);
            rod(scene, "rod", xs.iter().map(|x| ([0.0; 3], tip(x))), 0.02);
            ball(scene, "bob", xs.iter().map(tip), 0.1);
            scene.add_target([0.0, 0.0, 1.0], 0.12);
        }
        // x = (y, θ, ẏ, θ̇): the cart at y, the pole of length 1.
        "cartpole" => {
            let cart = |x: &Vec<f64>| [0.0, x[0], 0.0];
            let tip = |x: &Vec<f64>| {
                let t = turned(x[1], 0.0, 1.0);
                [0.0, x[0] + t[1], t[2]]
            };
            scene.add_body(
                "cart",
                Shape::Box { size: [0.2, 0.3, 0.15] },
                xs.iter().map(|x| Pose::at(cart(x))).collect(),
            );
            rod(scene, "pole", xs.iter().map(|x| (cart(x), tip(x))), 0.02);
            ball(scene, "bob", xs.iter().map(tip), 0.1);
            scene.add_target([0.0, 0.0, 1.0], 0.12);
        }
        // x = ((cos θ₁, sin θ₁), (cos θ₂, sin θ₂), θ̇₁, θ̇₂): the elbow at 0.1 m on link 1,
        // link 2 drawn 0.2 m long.
        "acrobot" | "acrobot-bounds" => {
            let phis = |x: &Vec<f64>| {
                let p1 = angle(x[0], x[1]);
                (p1, p1 + angle(x[2], x[3]))
            };
            let elbow = |x: &Vec<f64>| turned(phis(x).0, 0.0, 0.1);
            let tip = |x: &Vec<f64>| {
                let (e, t) = (elbow(x), turned(phis(x).1, 0.0, 0.2));
                [0.0, e[1] + t[1], e[2] + t[2]]
            };
            rod(scene, "link 1", xs.iter().map(|x| ([0.0; 3], elbow(x))), 0.015);
            rod(scene, "link 2", xs.iter().map(|x| (elbow(x), tip(x))), 0.015);
            scene.add_target([0.0, 0.0, 0.3], 0.03);
        }
        // x = (p_x, p_y, cos θ, sin θ): a car-sized box along its heading.
        "se2-car" => {
            let poses = xs
                .iter()
                .map(|x| Pose::rotated(2, angle(x[2], x[3]), [x[0], x[1], 0.05]))
                .collect();
            scene.add_body("car", Shape::Box { size: [0.4, 0.2, 0.1] }, poses);
            scene.add_target([0.0, 0.0, 0.05], 0.05);
        }
        _ => return false,
    }
    true
}
