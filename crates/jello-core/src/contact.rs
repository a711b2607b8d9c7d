//! Contacts between bodies: penalty springs between the points of different bodies, found
//! through a hashed uniform grid (the broad phase).
//!
//! **Method.** Every active point of a body is a ball of radius [`Body::contact_radius`] (half the
//! body's smallest lattice spacing). Two balls of different bodies that overlap are pushed apart
//! along the line between their centres by a penalty spring with the model's collision stiffness,
//! and damped with its collision damping: `(kCollision·depth − dCollision (vA − vB)·n)·n`, with
//! `depth = rA + rB − |pA − pB|` and `n` the unit vector from B to A; across `n` acts Coulomb
//! friction with the model's coefficient (see [`crate::friction`]; its cap uses the
//! pair's reduced mass). The force on B is exactly the opposite, so contacts conserve linear
//! momentum.
//!
//! **Limits.** Bodies keep a gap of about one radius between their cages at rest (the cage
//! encloses the skin, so skins rest a little apart); a point moving more than a radius per step
//! relative to another body can pass through it; two points at the same place exert no force (no
//! direction); and a body does not collide with itself.
//!
//! **Broad phase.** Points are sorted into cubic grid cells the size of the largest ball diameter
//! by a counting sort over a hash of the cell; each point then looks at the 27 cells around its
//! own. Buffers are sized once, so a pass allocates nothing; the sums run in a fixed order, so the
//! forces are bit for bit the same whatever the thread count.

use crate::body::Body;
use crate::model::Model;
use crate::soa::Soa;
use crate::vec3::Vec3;

/// The buffers of the contact pass, sized once for a model.
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    /// Contact force on every point (N).
    forces: Soa,
    /// Bucket starts of the hashed grid (`buckets + 1` entries).
    starts: Vec<u32>,
    /// Active points sorted by bucket; in each bucket by index.
    entries: Vec<u32>,
    /// Per sorted entry: its grid cell.
    entry_cells: Vec<[i32; 3]>,
    /// Per sorted entry: its body.
    entry_body: Vec<u32>,
    /// Per point: its grid cell (for the sort).
    point_cells: Vec<[i32; 3]>,
    /// Per body: the ball radius (m).
    radius: Vec<f64>,
    /// Per body: the mass of a point (kg), for the friction's cap.
    mass: Vec<f64>,
    /// The pairs of balls that overlapped in the last [`Contacts::compute`], once each.
    pairs: Vec<Pair>,
    /// Side of a grid cell (m).
    cell: f64,
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
        let buckets = (2 * active).next_power_of_two();
        Contacts {
            forces: Soa::zeros(n),
            starts: vec![0; buckets + 1],
            entries: vec![0; active],
            entry_cells: vec![[0; 3]; active],
            entry_body: vec![0; active],
            point_cells: vec![[0; 3]; n],
            radius,
            mass: bodies.iter().map(|b| b.material.mass).collect(),
            // Room for 8 a point (two lattices of the same spacing touch at most 8 points of
            // the other), so that stepping does not allocate.
            pairs: Vec::with_capacity(8 * active),
            cell,
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
            starts,
            entries,
            entry_cells,
            entry_body,
            point_cells,
            radius,
            mass,
            pairs,
            cell,
        } = self;
        forces.fill_zero();
        pairs.clear();
        if bodies.len() < 2 {
            return;
        }
        let inv = 1.0 / *cell;
        let (px, py, pz) = (p.x(), p.y(), p.z());
        let mask = starts.len() - 2;
        // Counting sort of the active points by bucket.
        starts.fill(0);
        for body in bodies {
            for q in active_points(body) {
                let c = [px[q], py[q], pz[q]].map(|x| (x * inv).floor() as i32);
                point_cells[q] = c;
                starts[hash(c) & mask] += 1;
            }
        }
        let mut sum = 0;
        for s in starts.iter_mut() {
            let count = *s;
            *s = sum;
            sum += count;
        }
        for (b, body) in bodies.iter().enumerate() {
            for q in active_points(body) {
                let c = point_cells[q];
                let slot = &mut starts[hash(c) & mask];
                let e = *slot as usize;
                (entries[e], entry_cells[e], entry_body[e]) = (q as u32, c, b as u32);
                *slot += 1;
            }
        }
        // Each bucket's start is now the next one's; shift back.
        for b in (1..starts.len()).rev() {
            starts[b] = starts[b - 1];
        }
        starts[0] = 0;
        // Each active point sums the forces from the other bodies' balls around it.
        let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
        let (vx, vy, vz) = (v.x(), v.y(), v.z());
        let [fx, fy, fz] = forces.parts_mut();
        let grid = Grid {
            starts: &starts[..],
            entries: &entries[..],
            entry_cells: &entry_cells[..],
            entry_body: &entry_body[..],
        };
        for (b, body) in bodies.iter().enumerate() {
            for a in active_points(body) {
                let (pa, va) = (
                    Vec3::new(px[a], py[a], pz[a]),
                    Vec3::new(vx[a], vy[a], vz[a]),
                );
                let mut f = Vec3::ZERO;
                grid.for_each_near(body, point_cells[a], |e, eb| {
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

/// The hashed grid of the active points, as [`Contacts::compute`] sorted them.
struct Grid<'a> {
    starts: &'a [u32],
    entries: &'a [u32],
    entry_cells: &'a [[i32; 3]],
    entry_body: &'a [u32],
}

impl Grid<'_> {
    /// Calls `near(e, body of e)` for every active point `e` of a body other than `body` in the
    /// 27 grid cells around `cell`, in a fixed order.
    #[inline]
    fn for_each_near(&self, body: &Body, cell: [i32; 3], mut near: impl FnMut(usize, usize)) {
        let mask = self.starts.len() - 2;
        let own = body.points();
        for n in 0..27 {
            let d = [n / 9 - 1, n / 3 % 3 - 1, n % 3 - 1];
            let around = [
                cell[0].wrapping_add(d[0]),
                cell[1].wrapping_add(d[1]),
                cell[2].wrapping_add(d[2]),
            ];
            let bucket = hash(around) & mask;
            let range = self.starts[bucket] as usize..self.starts[bucket + 1] as usize;
            let candidates = self.entries[range.clone()]
                .iter()
                .zip(&self.entry_cells[range.clone()])
                .zip(&self.entry_body[range]);
            for ((&e, &ec), &eb) in candidates {
                // Another cell hashed to the same bucket, or the same body: skip.
                let e = e as usize;
                if ec != around || own.contains(&e) {
                    continue;
                }
                near(e, eb as usize);
            }
        }
    }
}

/// The active points of a body, as flat indices of the model.
fn active_points(body: &Body) -> impl Iterator<Item = usize> + '_ {
    body.points()
        .filter(move |&q| body.is_active(q - body.points().start))
}

/// A hash of a grid cell (the three large primes of Teschner et al. 2003).
#[inline]
fn hash(c: [i32; 3]) -> usize {
    ((c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791)) as usize
}

/// The penalty force on ball A from ball B at separation `d = pA − pB` and relative velocity
/// `w = vA − vB`, when they overlap (`|d| < reach`): exactly minus the force on B from A.
/// `[kc, dc, mu, c_max]`: collision stiffness and damping, and the friction coefficient with its
/// cap (see [`crate::friction`]).
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
        f += crate::friction::sliding(n, w, mu * normal, c_max);
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
