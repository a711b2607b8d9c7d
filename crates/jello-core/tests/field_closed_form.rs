//! `ForceField` sampling against a closed form. Trilinear interpolation reproduces any function
//! that is trilinear in (x, y, z) (an affine map plus xy, yz, xz and xyz terms) exactly, so a
//! field whose nodes hold such a function `f`, at the node positions docs/spec.md gives, must sample
//! to `f(p)` everywhere inside the box, and to `f(clamped p)` outside it.
//!
//! Independent of the code: the nodes are placed and stored here by docs/spec.md's rules (node
//! `(i, j, k)` at `(−2 + 4i/(res−1), …)`, stored at `i*res*res + j*res + k`, and in a world file
//! i outermost, k innermost), not by `ForceField::from_fn`. `f` has a different coefficient on
//! every term, so swapping two axes, reversing one or transposing the storage order changes the
//! sampled values at order 1.
//!
//! Tolerance: 1e-12 of the field's scale. Interpolation rounds a few dozen operations on node
//! values of at most ~20 N (~1e-14 N); an indexing or axis mistake is off by ~1 N.

mod common;

use common::Lcg;
use jello_core::{Aabb, ForceField, ReadOptions, Vec3, World};

/// A trilinear force (N) with distinct coefficients on every term.
fn f(p: Vec3) -> Vec3 {
    let (x, y, z) = (p.x, p.y, p.z);
    Vec3::new(
        1.0 + 2.0 * x - 3.0 * y + 0.5 * z + 0.75 * x * y * z,
        -4.0 + 0.25 * x + 1.5 * y - 2.0 * z - 1.25 * x * y + 0.5 * y * z,
        0.5 - 1.0 * x + 0.125 * y + 3.0 * z + 0.625 * x * z - 0.375 * x * y * z,
    )
}

/// Largest |f| over the box is below this (N).
const SCALE: f64 = 40.0;

/// Node `i` of `res` along any axis, by docs/spec.md.
fn node(i: usize, res: usize) -> f64 {
    -2.0 + 4.0 * i as f64 / (res - 1) as f64
}

/// The node forces in docs/spec.md's order: `(i, j, k)` at `i*res*res + j*res + k`.
fn nodes(res: usize) -> Vec<Vec3> {
    let mut forces = Vec::with_capacity(res * res * res);
    for i in 0..res {
        for j in 0..res {
            for k in 0..res {
                assert_eq!(forces.len(), i * res * res + j * res + k);
                forces.push(f(Vec3::new(node(i, res), node(j, res), node(k, res))));
            }
        }
    }
    forces
}

fn clamp(p: Vec3) -> Vec3 {
    Vec3::new(
        p.x.clamp(-2.0, 2.0),
        p.y.clamp(-2.0, 2.0),
        p.z.clamp(-2.0, 2.0),
    )
}

fn assert_samples(field: &ForceField, p: Vec3, what: &str) {
    let (got, want) = (field.sample(p), f(clamp(p)));
    assert!(
        (got - want).max_abs() <= 1e-12 * SCALE,
        "{what}: at {p:?} sampled {got:?}, f gives {want:?}"
    );
}

/// Random points inside the box, points on and near the faces and the nodes themselves.
#[test]
fn inside_the_box_sampling_is_the_trilinear_function() {
    for res in [2, 3, 4, 7, 16, 30] {
        let field = ForceField::new(res, Aabb::classic(), nodes(res)).unwrap();
        let what = format!("res {res}");
        let mut rng = Lcg(res as u64);
        for _ in 0..2000 {
            assert_samples(&field, rng.vec3() * 2.0, &what);
        }
        // Every node, and the midpoints of the first cells.
        for i in 0..res {
            for (j, k) in [(0, res - 1), (res / 2, 1), (res - 1, 0)] {
                let p = Vec3::new(node(i, res), node(j, res), node(k, res));
                assert_samples(&field, p, &what);
                let h = 2.0 / (res - 1) as f64;
                assert_samples(&field, clamp(p + Vec3::new(h, -h, h)), &what);
            }
        }
        // The faces, edges and corners of the box.
        for c in [-2.0, 2.0] {
            for _ in 0..50 {
                let (a, b) = (rng.next() * 2.0, rng.next() * 2.0);
                for p in [Vec3::new(c, a, b), Vec3::new(a, c, b), Vec3::new(a, b, c)] {
                    assert_samples(&field, p, &what);
                }
            }
            assert_samples(&field, Vec3::new(c, c, -c), &what);
        }
    }
}

/// Outside the box a point samples the field at the point clamped into the box (face, edge or
/// corner).
#[test]
fn outside_the_box_sampling_is_the_clamped_value() {
    for res in [2, 5, 30] {
        let field = ForceField::new(res, Aabb::classic(), nodes(res)).unwrap();
        let what = format!("res {res}");
        let mut rng = Lcg(100 + res as u64);
        for _ in 0..2000 {
            // Up to 6 m from the centre: most points outside on one, two or three axes.
            let p = rng.vec3() * 6.0;
            assert_samples(&field, p, &what);
        }
        for p in [
            Vec3::new(1e9, 0.5, -0.25),
            Vec3::new(-3.0, -1e300, 2.5),
            Vec3::new(2.0 + 1e-12, 1.0, 1.0),
        ] {
            assert_samples(&field, p, &what);
        }
    }
}

/// `from_fn` puts its nodes where docs/spec.md says and stores them in docs/spec.md's order.
#[test]
fn from_fn_uses_the_spec_node_positions_and_order() {
    for res in [2, 3, 9] {
        let field = ForceField::from_fn(res, Aabb::classic(), f).unwrap();
        let want = nodes(res);
        for (n, (got, want)) in field.forces().iter().zip(&want).enumerate() {
            assert!(
                (*got - *want).max_abs() <= 1e-12 * SCALE,
                "res {res}, node {n}"
            );
        }
    }
}

/// A world file's field triples, i outermost and k innermost, become that same field.
#[test]
fn world_file_field_order() {
    let res = 4;
    let mut text = String::from("RK4\n0.0005 1\n200 0.25 400 0.25\n0.001953\n0\n4\n");
    for i in 0..res {
        for j in 0..res {
            for k in 0..res {
                let v = f(Vec3::new(node(i, res), node(j, res), node(k, res)));
                text += &format!("{:?} {:?} {:?}\n", v.x, v.y, v.z);
            }
        }
    }
    for n in 0..512 {
        let (i, j, k) = (n / 64, (n / 8) % 8, n % 8);
        text += &format!("{} {} {}\n", i as f64 / 7.0, j as f64 / 7.0, k as f64 / 7.0);
    }
    text += &"0 0 0\n".repeat(512);
    let world = World::parse(text.as_bytes(), "field.w", ReadOptions::default()).unwrap();
    let (model, _) = world.to_simulation().unwrap();
    let field = model.field.expect("a field");
    assert_eq!(field.res(), res);
    let mut rng = Lcg(9);
    for _ in 0..1000 {
        assert_samples(&field, rng.vec3() * 2.5, "world file");
    }
}
