//! Under self-contact, cells kept from turning inside out.
//!
//! Self-contact finds a body's surface points in its own cells by each cell's distance to the
//! surface at rest, carried over the cell as it deforms (see [`super::bodies`]). A cell crushed
//! until its corners pass each other no longer maps its rest shape onto one region: it overlaps
//! its neighbours, or folds back onto the side of its neighbour, and a surface point moving
//! across a face of it is found at one pass several millimetres inside the surface and at the
//! next in no cell at all. That force, switched on and off between passes, is not the gradient
//! of anything: `ring.toml`'s torus under its 150 kg block kept 0.06 J of jitter at the ends of
//! its closed hole after 6 s (0.1–0.3 m/s at the fold's vertices, 0.4–1.9 mm crossings
//! there), backward Euler took 6.6 Newton iterations a step on it, and the same ring with a
//! finer cage (16 or 20 cells) blew up.
//!
//! So a body under self-contact also resists losing the volume at each corner of each of its
//! cells: at a corner `c` with neighbours `u`, `v`, `w` along the cell's three axes, the volume
//! `D = (eᵤ × eᵥ)·e_w` of its edges `eₐ = ±(xₐ − x_c)` (each signed to point along its axis, so
//! that `D = hₓ·h_y·h_z` at rest and `D < 0` where the corner has turned inside out). Below
//! [`FROM`] of its rest volume `D₀`, a penalty energy `½·k·(FROM·D₀ − D)²` pushes it back out,
//! with `k` [`STIFFNESS`] times the body's structural spring stiffness over its spacing to the
//! fourth (an energy of the springs' scale: `k·D₀²` is `STIFFNESS·kₛ·h²` on a cube's lattice).
//! Its forces are minus the energy's gradient, `(FROM·D₀ − D)·k·∂D/∂x` on the four points
//! (`∂D/∂xᵤ = ±eᵥ × e_w`, …, the corner's minus their sum): they sum to zero and exert no
//! torque, and do nothing to a cell less squeezed (a body at rest, or bent and stretched as
//! bodies usually are). The implicit integrators add the energy's Gauss–Newton curvature at
//! each point (`k·(∂D/∂x)(∂D/∂x)ᵀ`, positive semi-definite) to `A`'s diagonal blocks.
//!
//! The ring with it settles (5·10⁻⁵ J of kinetic energy at 6 s), no face of it crosses another
//! once the block has landed (12 pairs 0.23 mm deep for a moment as it lands), and its cage
//! made of 16 or 20 cells runs (see docs/scenes.md).

use crate::model::Model;
use crate::vec3::Vec3;

/// The fraction of a corner's volume at rest below which the guard pushes it back out.
pub const FROM: f64 = 0.5;

/// The guard's stiffness, times the body's structural spring stiffness over its smallest
/// lattice spacing to the fourth. On `ring.toml`'s torus with 16 cells, 5 (starting at half the
/// volume) settled as well as 30 starting at a quarter, and 10 at a quarter let cells turn.
pub const STIFFNESS: f64 = 5.0;

/// A corner of a cell squeezed below [`FROM`] of its volume at rest: its point and its three
/// neighbours' (flat indices into the model's points), the gradient of its volume with respect
/// to each, the guard's push (`k·(FROM·D₀ − D)`, > 0) and its stiffness `k`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Squeezed {
    pub points: [usize; 4],
    pub gradient: [Vec3; 4],
    pub push: f64,
    pub stiffness: f64,
}

impl Squeezed {
    /// The guard's force on each of the four points: `gradient·push`.
    pub(crate) fn forces(&self) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        (self.points.iter().zip(&self.gradient)).map(|(&p, &g)| (p, g * self.push))
    }

    /// Its energy, `½·k·(FROM·D₀ − D)²` (J).
    pub(crate) fn energy(&self) -> f64 {
        0.5 * self.push * self.push / self.stiffness
    }
}

/// Calls `each` for every squeezed corner of `model`'s bodies at positions `at`, body by body,
/// cell by cell (in the order of [`crate::model::contact_surface::ContactSurface::cells`]) and
/// corner by corner: always in that order. Nothing without self-contact.
pub(crate) fn for_each_squeezed(
    model: &Model,
    at: impl Fn(usize) -> Vec3,
    mut each: impl FnMut(&Squeezed),
) {
    if !model.self_contact {
        return;
    }
    for body in model.bodies() {
        let surface = body.contact_surface();
        let h = body.lattice().spacing();
        let rest = h.x * h.y * h.z;
        if rest <= 0.0 {
            // A row or a sheet one point thick: no volume to keep.
            continue;
        }
        let stiffness = STIFFNESS * body.material.stiffness[0] / body.min_spacing().powi(4);
        let first = body.points().start;
        let offsets = surface.corner_offsets();
        for &cell in surface.cells() {
            let base = first + cell as usize;
            // Corner `c`'s bits are its (u, v, w) place in the cell (4, 2, 1): its neighbour
            // along an axis flips that bit, and the edge to it points along the axis from the
            // corner with the bit clear.
            for c in 0..8 {
                let sign = |bit: usize| if c & bit == 0 { 1.0 } else { -1.0 };
                let corner = base + offsets[c];
                let [u, v, w] = [4, 2, 1].map(|bit| base + offsets[c ^ bit]);
                let x = at(corner);
                let [eu, ev, ew] = [(u, 4), (v, 2), (w, 1)].map(|(p, bit)| (at(p) - x) * sign(bit));
                let volume = eu.cross(ev).dot(ew);
                let short = FROM * rest - volume;
                // (Not a number where a point is not: the step's blow-up check tells of that.)
                if short.is_nan() || short <= 0.0 {
                    continue;
                }
                let gu = ev.cross(ew) * sign(4);
                let gv = ew.cross(eu) * sign(2);
                let gw = eu.cross(ev) * sign(1);
                each(&Squeezed {
                    points: [corner, u, v, w],
                    gradient: [-(gu + gv + gw), gu, gv, gw],
                    push: stiffness * short,
                    stiffness,
                });
            }
        }
    }
}

/// The guards' energy at positions `pos` (J): a diagnostic.
pub fn energy(model: &Model, pos: &[Vec3]) -> f64 {
    let mut energy = 0.0;
    for_each_squeezed(model, |p| pos[p], |s| energy += s.energy());
    energy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::body::{Body, Material};
    use crate::model::lattice::Lattice;
    use crate::model::{Aabb, ModelBuilder};

    /// One cell (2×2×2 points, spacing 0.1 m, springs of 100 N/m), under self-contact or not.
    fn cell(self_contact: bool) -> Model {
        let lattice = Lattice::new([2, 2, 2], Vec3::new(0.1, 0.1, 0.1));
        let material = Material {
            mass: 0.01,
            stiffness: [100.0; 3],
            damping: [0.0; 3],
        };
        ModelBuilder::new()
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .bodies(vec![Body::lattice_box(lattice, material)])
            .self_contact(self_contact)
            .build()
            .unwrap()
    }

    /// The cell's corner (1, 1, 1) pushed along the diagonal toward (0, 0, 0) by `t` of the
    /// diagonal.
    fn squashed(model: &Model, t: f64) -> Vec<Vec3> {
        let body = &model.bodies()[0];
        let mut pos = body.rest_positions();
        let top = pos.len() - 1;
        pos[top] -= Vec3::new(0.1, 0.1, 0.1) * t;
        pos
    }

    fn forces(model: &Model, pos: &[Vec3]) -> Vec<Vec3> {
        let mut f = vec![Vec3::ZERO; pos.len()];
        for_each_squeezed(
            model,
            |p| pos[p],
            |s| s.forces().for_each(|(p, force)| f[p] += force),
        );
        f
    }

    /// At rest, and with the corner a tenth of the way in (its corner's volume 0.7 of rest,
    /// the eigenvalues of its edges 0.1, 0.1 and 0.07 m), nothing; a fifth of the way in (0.4),
    /// the guard acts.
    #[test]
    fn a_cell_at_rest_or_barely_squeezed_feels_nothing() {
        let model = cell(true);
        for t in [0.0, 0.1] {
            assert!(forces(&model, &squashed(&model, t))
                .iter()
                .all(|f| *f == Vec3::ZERO));
            assert_eq!(energy(&model, &squashed(&model, t)), 0.0);
        }
        // ½·k·(0.5 − 0.4)²·D₀², k = 5·100 N/m / (0.1 m)⁴.
        let expected = 0.5 * 5.0 * 100.0 / 1e-4 * (0.1f64 * 1e-3).powi(2);
        let got = energy(&model, &squashed(&model, 0.2));
        assert!((got - expected).abs() < 1e-9 * expected, "{got} {expected}");
    }

    #[test]
    fn nothing_without_self_contact() {
        let model = cell(false);
        let pos = squashed(&model, 1.2);
        assert!(forces(&model, &pos).iter().all(|f| *f == Vec3::ZERO));
        assert_eq!(energy(&model, &pos), 0.0);
    }

    /// The corner (1, 1, 1) pushed past the cell's middle: its own corner's volume (and those
    /// of its three neighbours in the cell) fall below half, and the guard pushes it back along
    /// the diagonal. The forces are minus the energy's gradient (central differences), sum to
    /// zero and exert no torque.
    #[test]
    fn the_forces_are_minus_the_gradient_of_the_energy() {
        let model = cell(true);
        for t in [0.6, 1.0, 1.3] {
            let pos = squashed(&model, t);
            let f = forces(&model, &pos);
            let top = pos.len() - 1;
            assert!(f[top].x > 0.0 && (f[top].x - f[top].y).abs() < 1e-9 * f[top].x.abs());
            let step = 1e-7;
            for (p, fp) in f.iter().enumerate() {
                for axis in 0..3 {
                    let mut e = [0.0; 2];
                    for (k, s) in [-1.0, 1.0].into_iter().enumerate() {
                        let mut moved = pos.clone();
                        let mut d = [0.0; 3];
                        d[axis] = s * step;
                        moved[p] += Vec3::new(d[0], d[1], d[2]);
                        e[k] = energy(&model, &moved);
                    }
                    let minus_gradient = -(e[1] - e[0]) / (2.0 * step);
                    let got = fp.to_array()[axis];
                    assert!(
                        (got - minus_gradient).abs() <= 1e-5 * (1.0 + got.abs()),
                        "t {t}, point {p}, axis {axis}: force {got}, −∂E/∂x {minus_gradient}"
                    );
                }
            }
            let sum = f.iter().fold(Vec3::ZERO, |s, &f| s + f);
            let torque = pos
                .iter()
                .zip(&f)
                .fold(Vec3::ZERO, |s, (&x, &f)| s + x.cross(f));
            let scale = f.iter().map(|f| f.length()).fold(0.0, f64::max);
            assert!(sum.length() < 1e-12 * scale && torque.length() < 1e-12 * scale);
        }
    }
}
