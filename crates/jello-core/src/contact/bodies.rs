//! Contacts between bodies: penalty springs between the points of different bodies, found
//! through a hashed uniform grid (the broad phase).
//!
//! **Method.** Every active point of a body is a ball of radius [`Body::contact_radius`] (half the
//! body's smallest lattice spacing). Two balls of different bodies that overlap are pushed apart
//! along the line between their centres by a penalty spring with the model's collision stiffness,
//! and damped with its collision damping: `(kCollision·depth − dCollision (vA − vB)·n)·n`, with
//! `depth = rA + rB − |pA − pB|` and `n` the unit vector from B to A; across `n` acts Coulomb
//! friction with the model's coefficient (see [`crate::contact::friction`]; its cap uses the
//! pair's reduced mass). The force on B is exactly the opposite, so contacts conserve linear
//! momentum.
//!
//! **Limits.** Bodies keep a gap of about one radius between their cages at rest (the cage
//! encloses the skin, so skins rest a little apart); a point moving more than a radius per step
//! relative to another body can pass through it; two points at the same place exert no force (no
//! direction); and a body does not collide with itself.
//!
//! The points near each point are found by the broad phase ([`super::broad_phase`]).

use super::broad_phase::{active_points, BroadPhase};
use crate::compute::soa::Soa;
use crate::model::body::Body;
use crate::model::Model;
use crate::vec3::Vec3;

/// The buffers of the contact pass, sized once for a model.
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    /// Contact force on every point (N).
    forces: Soa,
    /// The active points sorted into a hashed grid.
    grid: BroadPhase,
    /// Per body: the ball radius (m).
    radius: Vec<f64>,
    /// Per body: the mass of a point (kg), for the friction's cap.
    mass: Vec<f64>,
    /// The pairs of balls that overlapped in the last [`Contacts::compute`], once each.
    pairs: Vec<Pair>,
}

impl Contacts {
    /// Buffers for `model`; empty (and never used) for a model of one body.
    pub fn new(model: &Model) -> Self {
        let bodies = model.bodies();
        if bodies.len() < 2 {
            return Contacts::default();
        }
        let n = model.point_count();
        let active: usize = bodies.iter().map(Body::active_count).sum();
        let radius: Vec<f64> = bodies.iter().map(Body::contact_radius).collect();
        let cell = 2.0 * radius.iter().copied().fold(0.0, f64::max);
        Contacts {
            forces: Soa::zeros(n),
            grid: BroadPhase::new(n, active, cell),
            radius,
            mass: bodies.iter().map(|b| b.material.mass).collect(),
            // Room for 8 a point (two lattices of the same spacing touch at most 8 points of
            // the other), so that stepping does not allocate.
            pairs: Vec::with_capacity(8 * active),
        }
    }

    /// True when the buffers fit `model`.
    pub(crate) fn fits(&self, model: &Model) -> bool {
        if model.bodies().len() < 2 {
            return true;
        }
        self.forces.len() == model.point_count() && self.radius.len() == model.bodies().len()
    }

    /// The contact forces of the last [`Contacts::compute`].
    pub fn forces(&self) -> &Soa {
        &self.forces
    }

    /// The contact forces between the bodies of `model` at positions `p` and velocities `v`.
    pub fn compute(&mut self, model: &Model, p: &Soa, v: &Soa) {
        let bodies = model.bodies();
        let Contacts {
            forces,
            grid,
            radius,
            mass,
            pairs,
        } = self;
        forces.fill_zero();
        pairs.clear();
        if bodies.len() < 2 {
            return;
        }
        let (px, py, pz) = (p.x(), p.y(), p.z());
        grid.sort(bodies, [px, py, pz]);
        // Each active point sums the forces from the other bodies' balls around it.
        let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
        let (vx, vy, vz) = (v.x(), v.y(), v.z());
        let [fx, fy, fz] = forces.parts_mut();
        for (b, body) in bodies.iter().enumerate() {
            for a in active_points(body) {
                let (pa, va) = (
                    Vec3::new(px[a], py[a], pz[a]),
                    Vec3::new(vx[a], vy[a], vz[a]),
                );
                let mut f = Vec3::ZERO;
                grid.for_each_near(body, grid.cell_of(a), |e, eb| {
                    let (pb, vb) = (
                        Vec3::new(px[e], py[e], pz[e]),
                        Vec3::new(vx[e], vy[e], vz[e]),
                    );
                    let reach = radius[b] + radius[eb];
                    let d = pa - pb;
                    if d.length_squared() >= reach * reach {
                        return;
                    }
                    let (ma, me) = (mass[b], mass[eb]);
                    if a < e {
                        let reduced = ma * me / (ma + me);
                        pairs.push(Pair {
                            a,
                            b: e,
                            reach,
                            reduced,
                        });
                    }
                    // The friction's cap: the pair's reduced mass over the step (none needed
                    // without friction, so no division per pair then).
                    let c_max = if mu > 0.0 {
                        ma * me / ((ma + me) * model.dt)
                    } else {
                        0.0
                    };
                    f += pair_force(d, va - vb, reach, [kc, dc, mu, c_max]);
                });
                (fx[a], fy[a], fz[a]) = (f.x, f.y, f.z);
            }
        }
    }

    /// The pairs of balls of different bodies that overlapped in the last
    /// [`Contacts::compute`], once each (`a < b`), in a fixed order.
    pub(crate) fn pairs(&self) -> &[Pair] {
        &self.pairs
    }
}

/// Two balls of different bodies that overlap: their points (`a < b`), the sum of their radii
/// (m) and the pair's reduced mass (kg: the friction's cap is that over the time step).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair {
    pub a: usize,
    pub b: usize,
    pub reach: f64,
    pub reduced: f64,
}

/// The penalty force on ball A from ball B at separation `d = pA − pB` and relative velocity
/// `w = vA − vB`, when they overlap (`|d| < reach`): exactly minus the force on B from A.
/// `[kc, dc, mu, c_max]`: collision stiffness and damping, and the friction coefficient with its
/// cap (see [`crate::contact::friction`]).
#[inline]
pub fn pair_force(d: Vec3, w: Vec3, reach: f64, [kc, dc, mu, c_max]: [f64; 4]) -> Vec3 {
    let l2 = d.length_squared();
    if !(l2 < reach * reach && l2 > 0.0) {
        return Vec3::ZERO;
    }
    let l = l2.sqrt();
    let n = d / l;
    let normal = kc * (reach - l);
    let mut f = n * (normal - dc * w.dot(n));
    if mu > 0.0 {
        f += crate::contact::friction::sliding(n, w, mu * normal, c_max);
    }
    f
}

/// Depth (m) of the deepest overlap between balls of different bodies, and the penalty energy
/// `Σ ½ kCollision depth²` over the pairs (J). By brute force over pairs of bodies' active
/// points: a diagnostic, never part of stepping.
pub fn overlap(model: &Model, pos: &[Vec3]) -> (f64, f64) {
    let bodies = model.bodies();
    let (mut deepest, mut energy) = (0.0f64, 0.0);
    for (i, a) in bodies.iter().enumerate() {
        for b in &bodies[i + 1..] {
            let reach = a.contact_radius() + b.contact_radius();
            for p in active_points(a) {
                for q in active_points(b) {
                    let depth = reach - (pos[p] - pos[q]).length();
                    if depth > 0.0 {
                        deepest = deepest.max(depth);
                        energy += 0.5 * model.k_collision * depth * depth;
                    }
                }
            }
        }
    }
    (deepest, energy)
}
