//! Exact accelerations at hand-placed points: past one wall, past an edge and a corner (one
//! penalty spring per wall crossed), exactly on a wall (none), on the wrong side of the plane,
//! with the plane's coefficients scaled (same force), the force field and control forces; and
//! one contact's restitution against the damped oscillator's closed form.
//!
//! Independent of the code: every expected value is docs/spec.md's formula written out in this file
//! (`kCollision·depth·n − dCollision (v·n) n`, over the mass), never a crate helper. The points
//! are the two ends of a 2-point lattice of rest length 1, placed exactly 1 m apart with equal
//! velocities: the spring's length is exactly its rest length and its ends do not move apart, so
//! its force is exactly zero and what remains is the obstacle's (and field's, control's) force.
//!
//! Tolerance: 1e-12 relative to the largest expected acceleration. Expected and computed values
//! differ only in the order of a dozen correctly rounded operations (a few ulp, ~1e-15); a wrong
//! sign, normal, depth, axis or missing term is wrong at order 1. Zero forces are checked exactly.

mod common;

use common::Lcg;
use jello_core::forces::accelerations;
use jello_core::{
    step, Aabb, Control, ForceField, Integrator, Lattice, Model, ModelBuilder, Plane, ReadOptions,
    Scratch, State, Vec3, World,
};

/// Collision and mass constants, all different, so that a swapped one shows.
const KC: f64 = 350.0;
const DC: f64 = 1.75;
const MASS: f64 = 0.0625;

/// A 2-point lattice along x of rest length 1 with distinct constants, in the classic box.
fn pair() -> ModelBuilder {
    ModelBuilder::new()
        .lattice(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)))
        .elastic(200.0, 0.5)
        .collision(KC, DC)
        .mass(MASS)
}

/// The pair's two points: `a` and `a + (1, 0, 0)` (exact for the dyadic numbers used here).
fn pair_at(a: Vec3) -> Vec<Vec3> {
    vec![a, a + Vec3::new(1.0, 0.0, 0.0)]
}

/// Accelerations under test.
fn acc(model: &Model, pos: &[Vec3], vel: &[Vec3], control: &Control) -> Vec<Vec3> {
    let mut a = vec![Vec3::ZERO; pos.len()];
    accelerations(model, pos, vel, control, &mut a);
    a
}

/// Unit vector along `axis`.
fn unit(axis: usize) -> Vec3 {
    let mut e = [0.0; 3];
    e[axis] = 1.0;
    Vec3::new(e[0], e[1], e[2])
}

/// docs/spec.md's penalty spring: `kc·depth·n − dc (v·n) n`.
fn penalty(depth: f64, n: Vec3, v: Vec3, kc: f64, dc: f64) -> Vec3 {
    n * (kc * depth) - n * (dc * v.dot(n))
}

/// docs/spec.md's box force on a point at `p` moving at `v`: one penalty spring per wall of
/// `[lo, hi]³` the point is strictly outside of, toward its projection on that wall.
fn walls_by_hand(p: Vec3, v: Vec3, lo: f64, hi: f64, kc: f64, dc: f64) -> Vec3 {
    let mut f = Vec3::ZERO;
    for (axis, c) in p.to_array().into_iter().enumerate() {
        // The wall at `lo` has inward normal +axis, the wall at `hi` −axis.
        if c < lo {
            f += penalty(lo - c, unit(axis), v, kc, dc);
        }
        if c > hi {
            f += penalty(c - hi, -unit(axis), v, kc, dc);
        }
    }
    f
}

/// docs/spec.md's plane force: on the side of `a x + b y + c z + d` opposite to `reference`'s, depth
/// `|a x + b y + c z + d| / |(a, b, c)|` and `n` the unit normal into the allowed side.
fn plane_by_hand(coeffs: [f64; 4], reference: Vec3, p: Vec3, v: Vec3) -> Vec3 {
    let [a, b, c, d] = coeffs;
    let value = |q: Vec3| a * q.x + b * q.y + c * q.z + d;
    let allowed = if value(reference) < 0.0 { -1.0 } else { 1.0 };
    let s = value(p);
    if s * allowed >= 0.0 {
        return Vec3::ZERO;
    }
    let norm = (a * a + b * b + c * c).sqrt();
    let n = Vec3::new(a, b, c) * (allowed / norm);
    penalty(s.abs() / norm, n, v, KC, DC)
}

/// Asserts `got` is within 1e-12 · `scale` of `want`, component by component.
fn assert_close(got: &[Vec3], want: &[Vec3], scale: f64, what: &str) {
    assert!(scale > 0.0, "{what}: nothing to compare");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (*g - *w).max_abs() <= 1e-12 * scale,
            "{what}, point {i}: got {g:?}, want {w:?}"
        );
    }
}

fn largest(v: &[Vec3]) -> f64 {
    v.iter().map(|a| a.max_abs()).fold(0.0, f64::max)
}

/// Past one wall, past an edge (two walls), past a corner (three), and exactly on a wall: the
/// acceleration is the sum of one penalty spring per wall crossed, over the mass.
#[test]
fn walls_edges_and_corners() {
    let model = pair().build().unwrap();
    let v = Vec3::new(0.75, -1.5, 2.25);
    let vel = vec![v; 2];
    for (a, walls) in [
        // Both points past the +y wall only.
        (Vec3::new(0.25, 2.5, -0.75), [1, 1]),
        // Both past the −z wall, deep.
        (Vec3::new(-1.125, 0.5, -3.875), [1, 1]),
        // The first past −x, the second exactly on the −x wall.
        (Vec3::new(-3.0, 0.5, 0.5), [1, 0]),
        // The second past +x and −y (an edge); the first past −y and exactly on +x.
        (Vec3::new(2.0, -2.25, 0.5), [1, 2]),
        // Both past −y and +z (an edge); the first also past −x (a corner).
        (Vec3::new(-2.5, -2.0625, 2.125), [3, 2]),
        // Both past +x, +y and −z: the corner.
        (Vec3::new(2.5, 3.0, -2.375), [3, 3]),
    ] {
        let pos = pair_at(a);
        let got = acc(&model, &pos, &vel, &Control::none());
        let want: Vec<Vec3> = pos
            .iter()
            .map(|&p| walls_by_hand(p, v, -2.0, 2.0, KC, DC) / MASS)
            .collect();
        // The cases cross the walls they say they cross.
        for (p, n) in pos.iter().zip(walls) {
            let crossed = p.to_array().iter().filter(|c| c.abs() > 2.0).count();
            assert_eq!(crossed, n, "{p:?}");
        }
        assert_close(&got, &want, largest(&want), &format!("pair at {a:?}"));
    }
}

/// A point exactly on a wall, edge or corner, moving out through it, feels nothing: docs/spec.md's
/// penalty acts only "strictly outside". Checked exactly (no spring force either).
#[test]
fn exactly_on_a_wall_is_zero() {
    let model = pair().build().unwrap();
    for (a, v) in [
        // The first point on the −x wall.
        (Vec3::new(-2.0, 0.5, 0.5), Vec3::new(-3.0, 1.0, -1.0)),
        // The second point on the +x wall.
        (Vec3::new(1.0, 0.5, 0.5), Vec3::new(3.0, 1.0, -1.0)),
        // Both on the −y wall.
        (Vec3::new(0.0, -2.0, 0.5), Vec3::new(0.5, -3.0, 1.0)),
        // Both on the edge of +y and −z.
        (Vec3::new(-0.5, 2.0, -2.0), Vec3::new(0.5, 3.0, -3.0)),
        // The first on the corner −x, +y, +z, the second on the edge +y, +z.
        (Vec3::new(-2.0, 2.0, 2.0), Vec3::new(-3.0, 3.0, 3.0)),
    ] {
        let pos = pair_at(a);
        let got = acc(&model, &pos, &[v, v], &Control::none());
        for (p, g) in pos.iter().zip(&got) {
            assert!(p.max_abs() <= 2.0);
            assert_eq!(*g, Vec3::ZERO, "point at {p:?} moving at {v:?}");
        }
    }
}

/// The whole classic cube at rest, its bottom layer 0.1 m below the floor and its x = max layer
/// past the +x wall: those layers get the walls' forces, the rest nothing. (Spring forces of the
/// undeformed cube are zero up to rounding, ~1e-11 m/s² against ~1e4.)
#[test]
fn a_cube_across_two_walls() {
    let model = ModelBuilder::new()
        .collision(KC, DC)
        .mass(MASS)
        .build()
        .unwrap();
    let offset = Vec3::new(1.03125, -0.5, -2.1);
    let pos: Vec<Vec3> = model
        .body(0)
        .lattice()
        .rest_positions()
        .iter()
        .map(|p| *p + offset)
        .collect();
    let v = Vec3::new(0.5, 0.25, -2.0);
    let vel = vec![v; pos.len()];
    let got = acc(&model, &pos, &vel, &Control::none());
    let want: Vec<Vec3> = pos
        .iter()
        .map(|&p| walls_by_hand(p, v, -2.0, 2.0, KC, DC) / MASS)
        .collect();
    let touching = want.iter().filter(|w| **w != Vec3::ZERO).count();
    assert_eq!(
        touching,
        64 + 64 - 8,
        "the bottom layer and the x = max layer"
    );
    assert_close(&got, &want, largest(&want), "cube across two walls");
}

/// On the wrong side of the plane: one penalty spring toward it. Scaling the coefficients by
/// any λ > 0 names the same plane: the same force. So does λ < 0, since the allowed side is the
/// one holding the reference point, whatever the sign of the coefficients.
#[test]
fn plane_on_the_wrong_side_and_scaled_coefficients() {
    // A tilted plane; the allowed side holds `reference`.
    let coeffs = [1.0, -2.0, 0.5, 0.75];
    let v = Vec3::new(-0.5, 1.25, 0.375);
    let vel = vec![v; 2];
    for (reference, a) in [
        // Allowed side positive (value 0.75 at the origin); the pair on the negative side.
        (Vec3::ZERO, Vec3::new(-1.0, 1.0, -0.5)),
        // Allowed side negative; the pair on the positive side.
        (Vec3::new(-1.0, 1.0, -0.5), Vec3::new(0.25, -0.5, 1.0)),
        // Allowed side positive; the first point out, the second exactly on the plane.
        (Vec3::ZERO, Vec3::new(-1.5, 0.125, 0.0)),
    ] {
        let want: Vec<Vec3> = pair_at(a)
            .iter()
            .map(|&p| plane_by_hand(coeffs, reference, p, v) / MASS)
            .collect();
        assert!(
            want[0] != Vec3::ZERO,
            "the first point is on the wrong side"
        );
        for lambda in [1.0, 3.0, 1e-3, 1e6, 0.1, -1.0, -2.5] {
            let scaled = coeffs.map(|c| c * lambda);
            let plane = Plane::facing(scaled, reference).unwrap();
            let model = pair().plane(Some(plane)).build().unwrap();
            let got = acc(&model, &pair_at(a), &vel, &Control::none());
            assert_close(
                &got,
                &want,
                largest(&want),
                &format!("λ = {lambda}, pair at {a:?}"),
            );
        }
    }
}

/// A point exactly on the plane feels nothing.
#[test]
fn exactly_on_the_plane_is_zero() {
    // x + y − 1 = 0 holds exactly at (0.25, 0.75, z) and (−0.75, 1.75, z).
    let plane = Plane::facing([1.0, 1.0, 0.0, -1.0], Vec3::new(5.0, 5.0, 0.0)).unwrap();
    let model = pair().plane(Some(plane)).build().unwrap();
    for a in [Vec3::new(0.25, 0.75, 0.5), Vec3::new(-0.75, 1.75, -1.0)] {
        let vel = vec![Vec3::new(-1.0, -1.0, 0.5); 2];
        let pos = pair_at(a);
        let got = acc(&model, &pos, &vel, &Control::none());
        assert_eq!(got[0], Vec3::ZERO, "on the plane at {a:?}");
        // The second point is on the allowed side (value +1).
        assert_eq!(got[1], Vec3::ZERO, "allowed side at {:?}", pos[1]);
    }
}

/// A world file's plane faces the side holding the centre of mass of its initial positions:
/// the cube starts below z = 1 (a plane written as `0 0 1 −1`, and as `0 0 −2 2`), is then
/// moved up rigidly so its top layers are past the plane, and those layers are pushed down.
#[test]
fn world_plane_faces_the_initial_centre_of_mass() {
    let rest = Lattice::classic().rest_positions();
    let start: Vec<Vec3> = rest.iter().map(|p| *p - Vec3::new(0.5, 0.5, 0.5)).collect();
    for plane in ["0 0 1 -1", "0 0 -2 2"] {
        let text = world_text(plane, &start);
        let world = World::parse(text.as_bytes(), "plane.w", ReadOptions::default()).unwrap();
        let (model, _) = world.to_simulation().unwrap();
        // Up by 0.75: the top layer at z = 1.25, the one below at 1.25 − 1/7 > 1, ...
        let pos: Vec<Vec3> = start
            .iter()
            .map(|p| *p + Vec3::new(0.0, 0.0, 0.75))
            .collect();
        let v = Vec3::new(0.25, 0.0, 1.5);
        let vel = vec![v; 512];
        let got = acc(&model, &pos, &vel, &Control::none());
        let (kc, dc, m) = (400.0, 0.25, 0.001953);
        let want: Vec<Vec3> = pos
            .iter()
            .map(|p| {
                let depth = p.z - 1.0;
                let n = Vec3::new(0.0, 0.0, -1.0);
                if depth > 0.0 {
                    penalty(depth, n, v, kc, dc) / m
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        assert!(want.iter().filter(|w| **w != Vec3::ZERO).count() >= 64);
        assert_close(&got, &want, largest(&want), plane);
    }
}

/// A world file's text by hand (docs/spec.md's layout): RK4, dt 0.0005, 200 0.25 400 0.25, mass
/// 0.001953, the plane `a b c d`, no field, positions, zero velocities.
fn world_text(plane: &str, pos: &[Vec3]) -> String {
    let mut s = format!("RK4\n0.0005 1\n200 0.25 400 0.25\n0.001953\n1\n{plane}\n0\n");
    pos.iter()
        .for_each(|p| s += &format!("{:?} {:?} {:?}\n", p.x, p.y, p.z));
    pos.iter().for_each(|_| s += "0 0 0\n");
    s
}

/// A trilinear force (N): interpolation reproduces it exactly (see field_closed_form.rs).
fn trilinear(p: Vec3) -> Vec3 {
    let (x, y, z) = (p.x, p.y, p.z);
    Vec3::new(
        0.5 + 0.25 * x - 0.125 * y + 0.375 * z + 0.0625 * x * y * z,
        -0.25 + 0.5 * x * y - 0.75 * z,
        1.0 - 0.5 * y * z + 0.25 * x * z,
    )
}

/// docs/spec.md's node positions and storage order, by hand.
fn field_by_hand(res: usize) -> Vec<Vec3> {
    let node = |i: usize| -2.0 + 4.0 * i as f64 / (res - 1) as f64;
    let mut forces = vec![Vec3::ZERO; res * res * res];
    for i in 0..res {
        for j in 0..res {
            for k in 0..res {
                forces[i * res * res + j * res + k] =
                    trilinear(Vec3::new(node(i), node(j), node(k)));
            }
        }
    }
    forces
}

/// The field and control forces add to the (here zero) spring force; acceleration is the total
/// over the mass. With a wall and the plane too, all four add.
#[test]
fn field_control_walls_and_plane_add_up() {
    let res = 5;
    let field = ForceField::new(res, Aabb::classic(), field_by_hand(res)).unwrap();
    let mut rng = Lcg(3);
    for with_obstacles in [false, true] {
        let reference = Vec3::ZERO;
        let coeffs = [0.0, 0.5, 1.0, 1.5];
        let mut builder = pair().field(Some(field.clone()));
        if with_obstacles {
            builder = builder.plane(Some(Plane::facing(coeffs, reference).unwrap()));
        }
        let model = builder.build().unwrap();
        for _ in 0..20 {
            // Inside the box, or (with obstacles) past the −z wall and the plane.
            let a = if with_obstacles {
                Vec3::new(-1.5 + rng.next(), rng.next(), -2.25 + 0.125 * rng.next())
            } else {
                Vec3::new(-1.0 + rng.next(), 1.5 * rng.next(), 1.5 * rng.next())
            };
            let pos = pair_at(a);
            let v = rng.vec3();
            let vel = vec![v; 2];
            let control = Control {
                forces: vec![rng.vec3() * 5.0, rng.vec3() * 5.0],
                ..Control::none()
            };
            let got = acc(&model, &pos, &vel, &control);
            let want: Vec<Vec3> = pos
                .iter()
                .zip(&control.forces)
                .map(|(&p, &c)| {
                    // Outside the box the field is read at the point clamped into it.
                    let q = Vec3::new(
                        p.x.clamp(-2.0, 2.0),
                        p.y.clamp(-2.0, 2.0),
                        p.z.clamp(-2.0, 2.0),
                    );
                    let mut f = trilinear(q) + c;
                    if with_obstacles {
                        f += walls_by_hand(p, v, -2.0, 2.0, KC, DC);
                        f += plane_by_hand(coeffs, reference, p, v);
                    }
                    f / MASS
                })
                .collect();
            if with_obstacles {
                assert!(
                    pos[0].z < -2.0 && plane_by_hand(coeffs, reference, pos[0], v) != Vec3::ZERO
                );
            }
            assert_close(&got, &want, largest(&want), &format!("pair at {a:?}"));
        }
    }
}

/// One contact: a point meeting a wall at speed `v0` is a damped oscillator `m u'' = −kc u −
/// dc u'` while in contact (u the depth), and leaves at `v0·exp(−ζπ/√(1−ζ²))`, `ζ = dc/(2√(kc m))`.
/// Every one of the six walls, with a tangential velocity the wall must leave alone (no friction
/// in docs/spec.md: exactly unchanged).
///
/// The pair lies along a wall (perpendicular to its normal) and moves as one, so its spring
/// stays exactly at rest and each point is a single point against the wall. RK4 at dt = 1e-6
/// (7000 steps a contact): the damping force jumps by `dc·v` where contact begins and ends, so the
/// step across each is first order, an error of at most `dc·dt/m ≈ 1.3e-4` of the speed each:
/// the tolerance is twice that (measured: 1.9e-5 at this dt, 6.2e-5 at 4e-6). Elsewhere RK4's
/// error is ~(ω dt)⁴ ≈ 4e-11. A damping 10 % off moves the ratio by 4.5 %.
#[test]
fn contact_restitution_matches_the_damped_oscillator() {
    let (kc, dc, m): (f64, f64, f64) = (400.0, 0.25, 1.0 / 512.0);
    let zeta = dc / (2.0 * (kc * m).sqrt());
    let expected = (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp();
    let v0 = 1.5;
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            // Pair along `along`, tangential motion along `tangent`.
            let (along, tangent) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut counts = [1; 3];
            counts[along] = 2;
            let model = ModelBuilder::new()
                .lattice(Lattice::new(counts, Vec3::new(1.0, 1.0, 1.0)))
                .elastic(200.0, 0.25)
                .collision(kc, dc)
                .mass(m)
                .dt(1e-6)
                .integrator(Integrator::Rk4)
                .build()
                .unwrap();
            // Start 1 mm inside the wall, moving toward it.
            let n_out = unit(axis) * side;
            let start = n_out * 1.999 + unit(tangent) * 0.25 - unit(along) * 0.5;
            let vt = unit(tangent) * 0.375;
            let mut state = State::new(vec![start, start + unit(along)], vec![n_out * v0 + vt; 2]);
            let mut scratch = Scratch::new(&model);
            let control = Control::none();
            let (mut entered, mut steps) = (false, 0);
            loop {
                step(&model, &mut state, &control, &mut scratch).unwrap();
                steps += 1;
                let out = state.pos[0].dot(n_out) - 2.0;
                entered |= out > 0.0;
                // Left the wall and moving away: free flight from here on.
                if entered && out < -1e-4 {
                    break;
                }
                assert!(steps < 100_000, "never left the wall");
            }
            let what = format!(
                "wall {} {}",
                if side < 0.0 { "−" } else { "+" },
                ["x", "y", "z"][axis]
            );
            for p in 0..2 {
                let v = state.vel[p];
                let ratio = -v.dot(n_out) / v0;
                assert!(
                    (ratio - expected).abs() < 2.0 * dc * model.dt / m * expected,
                    "{what}: restitution {ratio} vs {expected} (ζ = {zeta})"
                );
                assert_eq!(v - n_out * v.dot(n_out), vt, "{what}: tangential velocity");
            }
        }
    }
}
