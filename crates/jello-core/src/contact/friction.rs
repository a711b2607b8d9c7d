//! Coulomb friction: of obstacles (planes, spheres, solid boxes) on the points touching them,
//! of the walls and the inclined plane (with their own coefficient, [`Model::wall_friction`]: 0
//! in the classic worlds, whose docs/spec.md gives them none), and of contacts between bodies.
//!
//! **Obstacles stick.** A point that touches an obstacle is tied to an *anchor*, the place where
//! it came into contact, by a tangential spring of the collision stiffness and damper of the
//! collision damping: `Ft = −kCollision·Δt − dCollision·vt`, with `Δt` the point's offset from
//! its anchor across the contact normal and `vt` its velocity across it. The spring holds any
//! tangential load up to `μ` times the normal force `kCollision·depth` without sliding (a body
//! rests on a slope or on a ball); beyond that the force is clamped to the cone `|Ft| ≤
//! μ·kCollision·depth` and the anchor slides along behind the point, `μ·depth` away (kinetic
//! friction). Anchors are moved only between steps ([`Anchors::update`]), so every stage of a
//! step sees the same forces for the same positions and velocities, and the explicit integrators
//! stay stable at the collision spring's own time step.
//!
//! **Bodies slide with a cap.** Contacts between bodies change partners from step to step, so
//! they carry no anchors: their friction opposes the sliding velocity with `μ` times the normal
//! force, capped as a damper of the pair's reduced mass over the time step ([`sliding`]). That
//! cap keeps the explicit integrators stable, and is also its limit: a contact under a load below
//! `μ·normal` creeps at `(load/m)·dt` instead of sticking, so a body resting on another on a slope
//! slowly slides.
//!
//! A point touching an obstacle for the first time within a step has no anchor yet and feels
//! [`sliding`] friction until the step ends. Anchors live in the step's scratch, not in the state:
//! a run resumed from a saved state ties its touching points afresh where they are.

use crate::model::obstacle::{Obstacle, ObstacleContact};
use crate::model::Model;
use crate::vec3::Vec3;

/// The anchor of a point that touches nothing.
pub const NONE: Vec3 = Vec3::new(f64::NAN, f64::NAN, f64::NAN);

/// Coulomb friction of a contact without an anchor: at normal `n` (unit) between surfaces sliding
/// at `v` (relative velocity), pressed together by the normal force `normal` (N): against the
/// tangential velocity `vt`, of size `normal` while sliding (`normal` already carries `μ`), but
/// never more than `c_max·|vt|`.
///
/// The cap: exact Coulomb friction is a step in velocity, and an explicit integrator steps over
/// it and chatters. Capping it as a damper of coefficient `c_max = m/dt` (`m` the point's mass,
/// or the pair's reduced mass) is the most that stops the sliding within one step and stays
/// stable (`c·dt/m ≤ 1` for every explicit integrator here).
#[inline(always)]
pub fn sliding(n: Vec3, v: Vec3, normal: f64, c_max: f64) -> Vec3 {
    let vt = v - n * v.dot(n);
    let speed = vt.length();
    if speed > 0.0 && normal > 0.0 {
        vt * -(normal.min(c_max * speed) / speed)
    } else {
        Vec3::ZERO
    }
}

/// The friction of an obstacle on a point at `p` moving at `v`, touching it at `depth` (> 0)
/// along the unit normal `n`, tied to `anchor` (NaN: none yet): the tangential spring and damper
/// clamped to the Coulomb cone, or [`sliding`] friction with the cap `c_max` when there is no
/// anchor. `[kc, dc, mu]`: collision stiffness, damping and friction coefficient.
#[inline(always)]
pub fn obstacle(
    p: Vec3,
    v: Vec3,
    depth: f64,
    n: Vec3,
    anchor: Vec3,
    [kc, dc, mu]: [f64; 3],
    c_max: f64,
) -> Vec3 {
    let limit = mu * kc * depth;
    if anchor.x.is_nan() {
        return sliding(n, v, limit, c_max);
    }
    let f = across(p - anchor, n) * -kc - across(v, n) * dc;
    let size = f.length();
    if size > limit {
        f * (limit / size)
    } else {
        f
    }
}

/// The part of `a` across the unit normal `n`.
#[inline(always)]
fn across(a: Vec3, n: Vec3) -> Vec3 {
    a - n * a.dot(n)
}

/// The cap of [`sliding`] friction in the implicit integrators, for a contact of mass `mass`
/// (a point's, or a pair's reduced mass) at a step `dt` with collision stiffness `kc`: that mass
/// over the shorter of `dt` and the contact's own time `√(mass/kc)`. The explicit integrators
/// cap at `mass/dt` for their stability, and a stable explicit step is at most a few times the
/// contact's own time, so the two agree wherever the step resolves the contact (`dt` up to that
/// time) and differ by at most that factor where an explicit step is still stable. The implicit
/// ones need no cap for stability, but Coulomb's law jumps at zero sliding speed and Newton's
/// method needs it continuous: the cap keeps it so, and taken over `dt` at a frame-rate step it
/// would let a body resting on another on a slope slide at `2·g·sin θ·dt` (8 cm/s at 15° and
/// 1/60 s) instead of creeping at `2·g·sin θ·√(m/kc)`.
pub(crate) fn implicit_cap(mass: f64, dt: f64, kc: f64) -> f64 {
    let own = if kc > 0.0 { (mass / kc).sqrt() } else { dt };
    mass / dt.min(own)
}

/// What [`obstacle`]'s friction adds to the implicit integrators' Newton matrix
/// `A = M − h·∂F/∂v` (velocities `v` at the step's end, positions `p = x₀ + h·v`) at a point
/// moving at `v`: `c·(I − nnᵀ − eeᵀ)`, returned as `c` and the unit vector `e`, the sliding
/// force's direction (none: `eeᵀ` is zero). A tie that holds (`|f| ≤ μ·kc·depth`) is a spring and damper across the normal:
/// `c = h·(h·kc + dc)`; once it slides, its force keeps the limit's size and turns with the
/// offset and the velocity: `c = h·(h·kc + dc)·limit/|f|`, and nothing along the force `e`. No
/// anchor: [`sliding_tangent`]. No friction: nothing. The limit's growth with depth, which is
/// not symmetric, is [`limit_growth`]'s; the normal's turning is left out.
#[allow(clippy::too_many_arguments)]
pub(crate) fn obstacle_tangent(
    p: Vec3,
    v: Vec3,
    depth: f64,
    n: Vec3,
    anchor: Vec3,
    [kc, dc, mu]: [f64; 3],
    c_max: f64,
    h: f64,
) -> (f64, Option<Vec3>) {
    if mu <= 0.0 {
        return (0.0, None);
    }
    let limit = mu * kc * depth;
    if anchor.x.is_nan() {
        return sliding_tangent(n, v, limit, c_max, h);
    }
    let f = across(p - anchor, n) * -kc - across(v, n) * dc;
    let (size, c) = (f.length(), h * (h * kc + dc));
    if size > limit {
        (c * limit / size, Some(f * (1.0 / size)))
    } else {
        (c, None)
    }
}

/// What the growth of the friction limit `μ·kc·depth` with depth adds to the Newton matrix
/// where [`obstacle`]'s friction slides at that full size, given the force's direction `e` that
/// [`obstacle_tangent`] returns there (a tie beyond the cone, or a point without an anchor beyond
/// its cap; none where the friction holds, is capped or is zero, and its size does not depend on
/// the depth): the force `limit·e` grows by `μ·kc` per metre of depth, and the depth by a metre
/// per metre moved against `n`, so `A` (`−h²·∂F/∂p`) gains `h²·μ·kc·e·nᵀ`, returned as
/// `h²·μ·kc·e` (the row `nᵀ` left to the caller; `law` is `[kc, dc, μ]`). This part is not
/// symmetric (see the implicit solver's GMRES).
pub(crate) fn limit_growth(e: Option<Vec3>, [kc, _, mu]: [f64; 3], h: f64) -> Option<Vec3> {
    e.map(|e| e * (h * h * mu * kc))
}

/// What [`sliding`] friction (at normal `n`, relative velocity `v`, normal force `normal`, cap
/// `c_max`) adds to the Newton matrix of a step of size `h`, as [`obstacle_tangent`] returns it:
/// while the cap binds (`c_max·|vt| ≤ normal`) it is a damper across the normal, `c = h·c_max`;
/// beyond, the force keeps its size and turns with `vt`: `c = h·normal/|vt|`, nothing along `vt`
/// (`e` the force's direction, `−vt/|vt|`).
pub(crate) fn sliding_tangent(
    n: Vec3,
    v: Vec3,
    normal: f64,
    c_max: f64,
    h: f64,
) -> (f64, Option<Vec3>) {
    if normal <= 0.0 {
        return (0.0, None);
    }
    let vt = across(v, n);
    let speed = vt.length();
    if c_max * speed <= normal {
        (h * c_max, None)
    } else {
        (h * normal / speed, Some(vt * (-1.0 / speed)))
    }
}

/// A surface whose friction ties the points touching it to anchors: an obstacle (with the
/// model's [`Model::friction`]), or a wall of the box or the inclined plane (with its
/// [`Model::wall_friction`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    /// Obstacle `o` of the model.
    Obstacle(usize),
    /// Wall `w` of the box: 0 to 5 for −x, +x, −y, +y, −z, +z (see [`crate::Aabb::wall_contact`]).
    Wall(usize),
    /// The inclined plane.
    Plane,
}

impl Surface {
    /// The surface's contact with a point at `p`, if it touches it.
    #[inline]
    pub fn contact(self, model: &Model, p: Vec3) -> Option<ObstacleContact> {
        match self {
            Surface::Obstacle(o) => model.obstacles[o].contact(p),
            Surface::Wall(w) => model.bounds.wall_contact(p, w),
            Surface::Plane => model.plane.and_then(|pl| pl.contact(p)),
        }
    }

    /// False when the surface cannot touch a point at `p` (one test of a coordinate for a wall of
    /// the box, which touches only points past it; the sign of a plane's equation); true
    /// otherwise (then [`Surface::contact`] decides).
    #[inline(always)]
    pub fn may_touch(self, model: &Model, p: Vec3) -> bool {
        match self {
            Surface::Plane => model.plane.is_some_and(|pl| pl.on_forbidden_side(p)),
            Surface::Obstacle(o) => match model.obstacles[o] {
                Obstacle::Plane(pl) => pl.on_forbidden_side(p),
                _ => true,
            },
            Surface::Wall(w) => {
                let (axis, c) = (w / 2, p.to_array()[w / 2]);
                if w % 2 == 1 {
                    c > model.bounds.max.to_array()[axis]
                } else {
                    c < model.bounds.min.to_array()[axis]
                }
            }
        }
    }

    /// False when the surface cannot touch any of the points whose coordinates are `xyz` (for a
    /// wall of the box, none is past it: one pass over a coordinate that vectorises); true
    /// otherwise.
    pub fn may_touch_any(self, model: &Model, xyz: [&[f64]; 3]) -> bool {
        match self {
            Surface::Wall(w) => {
                let axis = w / 2;
                let c = xyz[axis];
                if w % 2 == 1 {
                    let bound = model.bounds.max.to_array()[axis];
                    any_past(c, |c| c > bound)
                } else {
                    let bound = model.bounds.min.to_array()[axis];
                    any_past(c, |c| c < bound)
                }
            }
            _ => true,
        }
    }

    /// The surface's contact with point `i` at `p`, its clearance taken off the depth (see
    /// [`Model::contacts_of`]).
    #[inline]
    pub fn contact_of(self, model: &Model, i: usize, p: Vec3) -> Option<ObstacleContact> {
        self.contact(model, p)
            .and_then(|c| c.less(model.clearance_of(i)))
    }

    /// The surface's friction coefficient.
    #[inline]
    pub fn friction(self, model: &Model) -> f64 {
        match self {
            Surface::Obstacle(_) => model.friction,
            Surface::Wall(_) | Surface::Plane => model.wall_friction,
        }
    }
}

/// Whether `past` holds for any of `c`: the tests or-ed together in lanes of eight, which
/// vectorises, where a fold of `f64::max` over the coordinates waits for each maximum in turn
/// (with six walls, that was half of the friction's part of a resting 16³ cube's residuals).
#[inline(always)]
fn any_past(c: &[f64], past: impl Fn(f64) -> bool) -> bool {
    let mut lanes = [false; 8];
    let mut chunks = c.chunks_exact(8);
    for chunk in &mut chunks {
        for (lane, &c) in lanes.iter_mut().zip(chunk) {
            *lane |= past(c);
        }
    }
    lanes.contains(&true) || chunks.remainder().iter().any(|&c| past(c))
}

/// The surfaces with friction anchors, in the anchors' order: the obstacles when the model has
/// friction, then the six walls and the inclined plane (when there is one) when it has wall
/// friction.
pub fn anchored_surfaces(model: &Model) -> impl Iterator<Item = Surface> + '_ {
    let obstacles = if model.friction != 0.0 {
        model.obstacles.len()
    } else {
        0
    };
    let walls = if model.wall_friction != 0.0 {
        6 + usize::from(model.plane.is_some())
    } else {
        0
    };
    (0..obstacles)
        .map(Surface::Obstacle)
        .chain((0..walls).map(|w| {
            if w < 6 {
                Surface::Wall(w)
            } else {
                Surface::Plane
            }
        }))
}

/// Per anchored surface ([`anchored_surfaces`]) and point, where the point is tied while it
/// touches the surface (NaN when it does not): the state of the surfaces' friction, carried
/// from step to step by the step's scratch. Empty when no surface has friction.
#[derive(Clone, Debug, Default)]
pub struct Anchors {
    /// `surfaces × points`, surface-major.
    at: Vec<Vec3>,
    points: usize,
    /// The anchored obstacles (all of them, or none without friction): the walls' anchors
    /// come after theirs.
    obstacles: usize,
    /// Per surface, false when none of its points has an anchor (a wall no point has reached
    /// since it last let go): [`Anchors::update`] then passes over it while no point reaches it.
    tied: Vec<bool>,
}

/// Anchors are equal when they hold the same anchors (however [`Anchors::update`] knows which
/// surfaces have none).
impl PartialEq for Anchors {
    fn eq(&self, other: &Anchors) -> bool {
        (self.at == other.at) && self.points == other.points && self.obstacles == other.obstacles
    }
}

impl Anchors {
    /// No anchors yet, for `model`.
    pub fn new(model: &Model) -> Self {
        let surfaces = anchored_surfaces(model).count();
        if surfaces == 0 {
            return Anchors::default();
        }
        let points = model.point_count();
        Anchors {
            at: vec![NONE; surfaces * points],
            points,
            obstacles: anchored_surfaces(model)
                .filter(|s| matches!(s, Surface::Obstacle(_)))
                .count(),
            tied: vec![false; surfaces],
        }
    }

    /// Becomes a copy of `other`, reusing its own buffer (a derived `clone_from` would allocate
    /// a new one each time).
    pub(crate) fn copy_from(&mut self, other: &Anchors) {
        self.at.clone_from(&other.at);
        self.points = other.points;
        self.obstacles = other.obstacles;
        self.tied.clone_from(&other.tied);
    }

    /// True when these anchors are for `model`'s points and anchored surfaces.
    pub fn fits(&self, model: &Model) -> bool {
        let surfaces = anchored_surfaces(model).count();
        if surfaces > 0 {
            self.points == model.point_count() && self.at.len() == surfaces * self.points
        } else {
            self.at.is_empty()
        }
    }

    /// True when no surface has friction (there are no anchors to keep).
    pub fn is_empty(&self) -> bool {
        self.at.is_empty()
    }

    /// The anchors of obstacle `o`, one per point (the model must have friction).
    pub fn of(&self, o: usize) -> &[Vec3] {
        &self.at[o * self.points..(o + 1) * self.points]
    }

    /// The anchors of wall `w` (0 to 5), or of the inclined plane for `w = 6`, one per point
    /// (the model must have wall friction).
    pub fn of_wall(&self, w: usize) -> &[Vec3] {
        self.of(self.obstacles + w)
    }

    /// Where point `i` is tied to `surface`, or [`NONE`] (also when the surface has no
    /// anchors).
    pub(crate) fn anchor(&self, surface: Surface, i: usize) -> Vec3 {
        let slot = match surface {
            Surface::Obstacle(o) if o < self.obstacles => o,
            Surface::Obstacle(_) => return NONE,
            Surface::Wall(w) => self.obstacles + w,
            Surface::Plane => self.obstacles + 6,
        };
        self.at.get(slot * self.points + i).copied().unwrap_or(NONE)
    }

    /// After a step, with the points at `pos`: a point that left an obstacle lets go; one that
    /// touches it and has no anchor is tied where it is; one whose offset from its anchor across
    /// the normal is past the Coulomb cone (`μ·depth`) drags the anchor along to the cone's edge.
    pub fn update(&mut self, model: &Model, pos: &[Vec3]) {
        if self.at.is_empty() {
            return;
        }
        // Each point's anchor on its own: on the team's threads, in chunks of points.
        let size = crate::compute::team::chunk_size(self.points, 4096);
        // The walls no point is past: the lattice's bounds first, when any wall has friction.
        let bounds = (model.wall_friction != 0.0).then(|| crate::compute::team::bounds(pos, size));
        for (slot, surface) in anchored_surfaces(model).enumerate() {
            // A wall that no point is past ties none (`may_touch` is false for every point):
            // where none was tied either, there is nothing to do (each wall's pass over the
            // points was 5 % of a resting 16³ cube's steps at 1/60 s, on one thread).
            let reached = match (surface, bounds) {
                (Surface::Wall(_), Some((lo, hi))) => {
                    surface.may_touch(model, lo) || surface.may_touch(model, hi)
                }
                _ => true,
            };
            if !reached && !self.tied[slot] {
                continue;
            }
            self.tied[slot] = reached;
            let mu = surface.friction(model);
            let anchors = &mut self.at[slot * self.points..(slot + 1) * self.points];
            crate::compute::team::for_each_chunk([anchors], size, &|c, [anchors]| {
                let first = c * size;
                let pos = &pos[first..first + anchors.len()];
                for (k, (anchor, &p)) in anchors.iter_mut().zip(pos).enumerate() {
                    // Most points are far from most walls: a coordinate's test first.
                    let contact = if surface.may_touch(model, p) {
                        surface.contact_of(model, first + k, p)
                    } else {
                        None
                    };
                    let Some(contact) = contact else {
                        *anchor = NONE;
                        continue;
                    };
                    if anchor.x.is_nan() {
                        *anchor = p;
                        continue;
                    }
                    let n = contact.normal;
                    let offset = p - *anchor;
                    let offset_t = offset - n * offset.dot(n);
                    let (length, reach) = (offset_t.length(), mu * contact.depth);
                    if length > reach {
                        *anchor = p - offset_t * (reach / length);
                    }
                }
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `any_past` finds a point past a bound wherever it is among the lanes and the remainder,
    /// however many points there are, and NaN is past nothing.
    #[test]
    fn any_past_finds_the_one_point_past_a_bound() {
        for n in 0..40 {
            let mut c: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
            if n > 3 {
                c[2] = f64::NAN;
            }
            assert!(!any_past(&c, |c| c > 1.0), "{n} points");
            for i in (0..n).filter(|&i| n <= 3 || i != 2) {
                let mut past = c.clone();
                past[i] = 2.0;
                assert!(any_past(&past, |c| c > 1.0), "{n} points, point {i} past");
            }
        }
    }

    /// A point that went past a wall and came back lets go of its anchor, though no point is
    /// past the wall any more (a wall no point reaches is passed over only once none is tied).
    #[test]
    fn a_wall_that_no_point_reaches_any_more_lets_go_of_its_anchors() {
        use crate::model::body::{Body, Material};
        use crate::model::lattice::Lattice;
        use crate::model::{Aabb, ModelBuilder};
        let lattice = Lattice::new([2, 2, 2], Vec3::new(0.1, 0.1, 0.1));
        let model = ModelBuilder::new()
            .bodies(vec![Body::lattice_box(lattice, Material::classic())])
            .bounds(Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0)).unwrap())
            .wall_friction(0.5)
            .build()
            .unwrap();
        let mut anchors = Anchors::new(&model);
        let inside: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new(0.1 * i as f64, 0.0, 0.0))
            .collect();
        let mut past = inside.clone();
        past[3].x = -1.01;
        anchors.update(&model, &past);
        assert_eq!(anchors.of_wall(0)[3], past[3], "tied where it touched");
        assert!(anchors.of_wall(0)[2].x.is_nan());
        for _ in 0..2 {
            anchors.update(&model, &inside);
            assert!(
                anchors.of_wall(0).iter().all(|a| a.x.is_nan()),
                "{:?}",
                anchors.of_wall(0)
            );
        }
    }

    #[test]
    fn a_tied_point_is_held_up_to_the_cone_and_no_further() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        let p = Vec3::new(0.01, 0.0, -0.001);
        let anchor = Vec3::new(0.0, 0.0, -0.0005);
        let law = [1000.0, 0.0, 0.5];
        // Inside the cone: the tangential spring alone (the normal offset is ignored).
        let f = obstacle(p, Vec3::ZERO, 0.1, n, anchor, law, 1.0);
        assert!((f - Vec3::new(-10.0, 0.0, 0.0)).max_abs() < 1e-12, "{f:?}");
        // Past it: clamped to μ·k·depth, still against the offset.
        let f = obstacle(p, Vec3::ZERO, 0.01, n, anchor, law, 1.0);
        assert!((f - Vec3::new(-5.0, 0.0, 0.0)).max_abs() < 1e-12, "{f:?}");
        // No anchor: sliding friction against the velocity, capped.
        let none = NONE;
        let v = Vec3::new(0.0, 2.0, -3.0);
        let f = obstacle(p, v, 0.1, n, none, law, 1.0);
        assert_eq!(f, Vec3::new(0.0, -2.0, 0.0));
        let f = obstacle(p, v, 0.1, n, none, law, 100.0);
        assert_eq!(f, Vec3::new(0.0, -50.0, 0.0));
    }
}
