//! The accelerations of a block of points once their spring forces are known: the force field,
//! the walls, the plane, the control, the contacts with other bodies, the obstacles with their
//! friction, the pulls, over the mass, plus gravity; pinned points and the unused corners of a
//! lattice with holes do not accelerate.

use std::ops::Range;

use crate::contact::friction::{self, Anchors, Surface};
use crate::contact::obstacles::{penalty, wall_force};
use crate::model::obstacle::Obstacle;
use crate::model::Model;
use crate::state::Pull;
use crate::vec3::Vec3;

/// What the acceleration of a block of points depends on besides the model: their positions,
/// velocities, spring forces and control forces.
#[derive(Clone, Copy)]
pub struct PointInputs<'a> {
    /// Positions (m), x, y and z.
    pub pos: [&'a [f64]; 3],
    /// Velocities (m/s), x, y and z.
    pub vel: [&'a [f64]; 3],
    /// Sum of the spring forces (N), x, y and z.
    pub spring: [&'a [f64]; 3],
    /// Control force on each point (N), or `None` for no control forces.
    pub control: Option<&'a [Vec3]>,
    /// Flat index of the block's first point.
    pub first: usize,
    /// The control's pulls (all of them; those on the block's points act).
    pub pulls: &'a [Pull],
    /// Mass of each point of the block (kg).
    pub mass: f64,
    /// Per point of the block whether it takes part, or `None` when all do. The others (the
    /// unused corners of a lattice with holes) do not accelerate.
    pub active: Option<&'a [bool]>,
    /// Contact force from other bodies on each point (N), x, y and z, or `None` for none.
    pub contact: Option<[&'a [f64]; 3]>,
    /// The obstacles' friction anchors (of every point; see [`crate::contact::friction`]), or `None`
    /// when there are none (friction off, or a force evaluation outside a step).
    pub anchors: Option<&'a Anchors>,
    /// How far each point of the block rests outside its body's skin (m), taken off its depth
    /// into the walls, the plane and the obstacles (see [`crate::model::clearance`]), or `None`
    /// for none (a body without a skin).
    pub clearance: Option<&'a [f64]>,
    /// Whether the obstacles' and the walls' friction acts. Not in the implicit integrators'
    /// residual passes: at zero velocity and without anchors it is zero (the integrators add it
    /// themselves), and computed for every point it took 2 % of a resting 16³ cube's steps.
    pub friction: bool,
}

crate::compute::simd::multiversion! {
    /// Accelerations of a block of points once their spring forces are known: spring force plus
    /// field, walls, plane and control, over the mass. Compiled for AVX-512 too (floors and
    /// selects in vector registers).
    pub fn block_accelerations(model: &Model, point: PointInputs<'_>, acc: [&mut [f64]; 3]) {
        block_accelerations_impl(model, point, acc)
    }
}

#[inline(always)]
fn block_accelerations_impl(model: &Model, point: PointInputs<'_>, acc: [&mut [f64]; 3]) {
    let [ax, ay, az] = acc;
    let len = ax.len();
    let (ay, az) = (&mut ay[..len], &mut az[..len]);
    let [px, py, pz] = point.pos.map(|c| &c[..len]);
    let [vx, vy, vz] = point.vel.map(|c| &c[..len]);
    let [sx, sy, sz] = point.spring.map(|c| &c[..len]);
    let control = point.control.map(|c| &c[..len]);
    let clearance = point.clearance.map(|c| &c[..len]);
    let (kc, dc, mass) = (model.k_collision, model.d_collision, point.mass);
    let (lo, hi) = (model.bounds.min, model.bounds.max);
    let obstacles = !model.obstacles.is_empty()
        || point.contact.is_some()
        || model.gravity != Vec3::ZERO
        || model.wall_friction > 0.0;
    let block = point.first..point.first + len;
    let pulls = point
        .pulls
        .iter()
        .any(|p| block.contains(&(p.point as usize)));
    // With obstacles, contacts, gravity or pulls, the force is finished (and divided by the mass) after
    // the main loop.
    let deferred = obstacles || pulls;

    // Spring force plus field. A uniform field (or none) is a constant; any other is sampled
    // point by point first.
    let constant = match &model.field {
        None => Some(Vec3::ZERO),
        Some(field) => field.uniform(),
    };
    if let (None, Some(field)) = (constant, &model.field) {
        for t in 0..len {
            let f = Vec3::new(sx[t], sy[t], sz[t]) + field.sample(Vec3::new(px[t], py[t], pz[t]));
            (ax[t], ay[t], az[t]) = (f.x, f.y, f.z);
        }
    }
    // Then walls, plane and control, over the mass: each a branch-free pass over the block (in
    // the L1 cache), the walls and the mass component by component, so that the compiler
    // vectorises them. (One loop over points doing all of it stayed scalar on the AVX2 tier: the
    // compiler would not split it by its invariant options.)
    // Every point's sum is taken in the same order as ever: spring force plus field, the wall
    // (`kCollision·depth·n − dCollision (v·n) n` with n = ±axis), the plane, the control, then
    // over the mass. A point with a clearance meets the walls that much further out.
    let walls = [(lo.x, hi.x), (lo.y, hi.y), (lo.z, hi.z)];
    let comps = [
        (&mut *ax, px, vx, sx),
        (&mut *ay, py, vy, sy),
        (&mut *az, pz, vz, sz),
    ];
    for (c, ((a, p, v, s), (lo, hi))) in comps.into_iter().zip(walls).enumerate() {
        let (a, p, v, s) = (&mut a[..len], &p[..len], &v[..len], &s[..len]);
        match (constant, clearance) {
            (Some(field), None) => {
                let field = field.to_array()[c];
                for t in 0..len {
                    a[t] = (s[t] + field) + wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
            (None, None) => {
                for t in 0..len {
                    a[t] += wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
            (Some(field), Some(out)) => {
                let (field, out) = (field.to_array()[c], &out[..len]);
                for t in 0..len {
                    let (lo, hi) = (lo - out[t], hi + out[t]);
                    a[t] = (s[t] + field) + wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
            (None, Some(out)) => {
                let out = &out[..len];
                for t in 0..len {
                    let (lo, hi) = (lo - out[t], hi + out[t]);
                    a[t] += wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
        }
    }
    if let Some(pl) = model.plane {
        let (norm, n) = (pl.normal_length(), pl.inward_normal());
        for t in 0..len {
            let (pi, vi) = (
                Vec3::new(px[t], py[t], pz[t]),
                Vec3::new(vx[t], vy[t], vz[t]),
            );
            let s = pl.value(pi);
            let (depth, touches) = match clearance {
                None => (s.abs() / norm, s * pl.side < 0.0),
                Some(out) => {
                    let depth = s.abs() / norm - out[t];
                    (depth, s * pl.side < 0.0 && depth > 0.0)
                }
            };
            let push = n * (kc * depth) - n * (dc * vi.dot(n));
            let push = if touches { push } else { Vec3::ZERO };
            (ax[t], ay[t], az[t]) = (ax[t] + push.x, ay[t] + push.y, az[t] + push.z);
        }
    }
    if let Some(control) = control {
        for (t, c) in control.iter().enumerate() {
            (ax[t], ay[t], az[t]) = (ax[t] + c.x, ay[t] + c.y, az[t] + c.z);
        }
    }
    if deferred {
        finish_forces(model, point, [&mut *ax, &mut *ay, &mut *az], &block);
    } else {
        for a in [&mut *ax, &mut *ay, &mut *az] {
            for a in a.iter_mut() {
                *a /= mass;
            }
        }
    }
    // Unused corners of a lattice with holes do not accelerate.
    if let Some(active) = point.active {
        let active = &active[..len];
        for a in [&mut *ax, &mut *ay, &mut *az] {
            for (a, &on) in a.iter_mut().zip(active) {
                *a = if on { *a } else { 0.0 };
            }
        }
    }
    // Pinned points do not accelerate.
    let pins = &model.pins;
    let from = pins.partition_point(|&p| (p as usize) < block.start);
    for &p in pins[from..]
        .iter()
        .take_while(|&&p| (p as usize) < block.end)
    {
        let t = p as usize - block.start;
        (ax[t], ay[t], az[t]) = (0.0, 0.0, 0.0);
    }
}

/// The rest of the force on a block (contacts with other bodies, obstacles, then pulls), then
/// over the mass, plus gravity.
#[inline(always)]
fn finish_forces(
    model: &Model,
    point: PointInputs<'_>,
    acc: [&mut [f64]; 3],
    block: &Range<usize>,
) {
    let [ax, ay, az] = acc;
    let (kc, dc, mass) = (model.k_collision, model.d_collision, point.mass);
    let friction = if point.friction { model.friction } else { 0.0 };
    let law = [kc, dc, friction];
    let c_max = mass / model.dt;
    if let Some(contact) = point.contact {
        for (a, c) in [&mut *ax, &mut *ay, &mut *az].into_iter().zip(contact) {
            for (a, c) in a.iter_mut().zip(c) {
                *a += c;
            }
        }
    }
    // Obstacles, one loop each over the block (branch-free, so each vectorises).
    for (o, obstacle) in model.obstacles.iter().enumerate() {
        let anchors = point.anchors.map(|a| &a.of(o)[block.clone()]);
        let force = [&mut *ax, &mut *ay, &mut *az];
        match *obstacle {
            Obstacle::Plane(pl) => {
                let (norm, inward) = (pl.normal_length(), pl.inward_normal());
                add_contacts(point, force, anchors, law, c_max, |p| {
                    pl.depth_with(p, norm, inward)
                })
            }
            Obstacle::Sphere(sphere) => {
                add_contacts(point, force, anchors, law, c_max, |p| sphere.depth(p))
            }
            Obstacle::Box(b) => {
                add_contacts(point, force, anchors, law, c_max, |p| b.solid_depth(p))
            }
        }
    }
    // Friction of the walls and the inclined plane (their penalty springs are above).
    if model.wall_friction > 0.0 && point.friction {
        let law = [kc, dc, model.wall_friction];
        let walls = 6 + usize::from(model.plane.is_some());
        for w in 0..walls {
            let surface = if w < 6 {
                Surface::Wall(w)
            } else {
                Surface::Plane
            };
            let anchors = point.anchors.map(|a| &a.of_wall(w)[block.clone()]);
            let force = [&mut *ax, &mut *ay, &mut *az];
            add_friction(model, point, force, anchors, law, c_max, surface);
        }
    }
    // Pulls on the block's points, in the order given.
    for pull in point.pulls {
        let Some(t) = (pull.point as usize).checked_sub(block.start) else {
            continue;
        };
        if t >= ax.len() {
            continue;
        }
        let p = Vec3::new(point.pos[0][t], point.pos[1][t], point.pos[2][t]);
        let v = Vec3::new(point.vel[0][t], point.vel[1][t], point.vel[2][t]);
        let f = pull.force(p, v);
        (ax[t], ay[t], az[t]) = (ax[t] + f.x, ay[t] + f.y, az[t] + f.z);
    }
    let g = model.gravity.to_array();
    for (a, g) in [ax, ay, az].into_iter().zip(g) {
        for a in a.iter_mut() {
            *a = *a / mass + g;
        }
    }
}

/// `force += friction` over a block for a surface whose penalty spring is added elsewhere (a
/// wall, the inclined plane), with the block's friction `anchors` (none: no anchors); `law` and
/// `c_max` as [`friction::obstacle`] takes them.
#[inline(always)]
fn add_friction(
    model: &Model,
    point: PointInputs<'_>,
    force: [&mut [f64]; 3],
    anchors: Option<&[Vec3]>,
    law: [f64; 3],
    c_max: f64,
    surface: Surface,
) {
    let [fx, fy, fz] = force;
    let len = fx.len();
    // Most blocks have no point past most walls: one pass over the block's coordinate first
    // (point by point, this loop's test was a third of the points' part of the force pass of a
    // cube resting on a floor with friction).
    if !surface.may_touch_any(model, point.pos.map(|c| &c[..len])) {
        return;
    }
    // A wall touches only points past it along its axis: a test of one coordinate, first.
    let past = |t: usize| match surface {
        Surface::Wall(w) => {
            let (axis, c) = (w / 2, point.pos[w / 2][t]);
            if w % 2 == 1 {
                c > model.bounds.max.to_array()[axis]
            } else {
                c < model.bounds.min.to_array()[axis]
            }
        }
        _ => true,
    };
    for t in 0..len {
        if !past(t) {
            continue;
        }
        let p = Vec3::new(point.pos[0][t], point.pos[1][t], point.pos[2][t]);
        let Some(contact) = surface.contact_of(model, point.first + t, p) else {
            continue;
        };
        let v = Vec3::new(point.vel[0][t], point.vel[1][t], point.vel[2][t]);
        let anchor = anchors.map_or(friction::NONE, |a| a[t]);
        let (depth, n) = (contact.depth, contact.normal);
        let f = friction::obstacle(p, v, depth, n, anchor, law, c_max);
        (fx[t], fy[t], fz[t]) = (fx[t] + f.x, fy[t] + f.y, fz[t] + f.z);
    }
}

/// `force += penalty` over a block for one obstacle given by `depth_normal(p)` (depth ≤ 0 for
/// none), with the block's friction `anchors` (none: no anchors); `law` and `c_max` as
/// [`penalty`] takes them.
#[inline(always)]
fn add_contacts(
    point: PointInputs<'_>,
    force: [&mut [f64]; 3],
    anchors: Option<&[Vec3]>,
    law: [f64; 3],
    c_max: f64,
    depth_normal: impl Fn(Vec3) -> (f64, Vec3),
) {
    let [fx, fy, fz] = force;
    let len = fx.len();
    let (fy, fz) = (&mut fy[..len], &mut fz[..len]);
    let [px, py, pz] = point.pos.map(|c| &c[..len]);
    let [vx, vy, vz] = point.vel.map(|c| &c[..len]);
    for t in 0..len {
        let p = Vec3::new(px[t], py[t], pz[t]);
        let (depth, n) = depth_normal(p);
        // Less the point's clearance (`x − 0` is `x` to the bit, so a body without one is as
        // ever).
        let depth = depth - point.clearance.map_or(0.0, |c| c[t]);
        let anchor = anchors.map_or(friction::NONE, |a| a[t]);
        let f = penalty(
            depth,
            n,
            p,
            Vec3::new(vx[t], vy[t], vz[t]),
            anchor,
            law,
            c_max,
        );
        (fx[t], fy[t], fz[t]) = (fx[t] + f.x, fy[t] + f.y, fz[t] + f.z);
    }
}
