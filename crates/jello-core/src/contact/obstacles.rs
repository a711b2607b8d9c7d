//! Contacts with the walls, the inclined plane and the obstacles: the penalty law
//! `kCollision·depth·n − dCollision (v·n) n` (docs/spec.md) with Coulomb friction across `n` (see
//! [`super::friction`]), in the branch-free forms the force kernel calls, and the deepest
//! penetration. Each obstacle's depth and normal are defined once, with its shape, in
//! [`crate::model::obstacle`].

use crate::model::Model;
use crate::vec3::Vec3;

/// The force along one axis of the walls at `lo` and `hi` on a point at `c` moving at `v`: the
/// branch-free sum over [`Aabb::wall_contacts`] along that axis, for the force kernel.
#[inline(always)]
pub(crate) fn wall_force(c: f64, v: f64, lo: f64, hi: f64, kc: f64, dc: f64) -> f64 {
    // Both walls' forces are computed and one is selected (no branch), so that loops over points
    // calling this vectorise: with branches the compiler kept the point pass scalar.
    let (below, above) = (kc * (lo - c) - dc * v, -(kc * (c - hi)) - dc * v);
    let beyond = if c > hi { above } else { 0.0 };
    if c < lo {
        below
    } else {
        beyond
    }
}

/// The penalty force of an obstacle's contact given in branch-free form (`depth ≤ 0` means
/// none): `(kCollision·depth − dCollision·(v·n))·n`, the walls' spring and damping along the
/// normal, plus Coulomb friction across it.
///
/// With a friction coefficient `mu > 0` (`[kc, dc, mu]`), the friction of a point at `p` tied to
/// `anchor` is added (see [`crate::contact::friction::obstacle`]); `c_max` is the point's mass over the time
/// step.
#[inline(always)]
pub(crate) fn penalty(
    depth: f64,
    n: Vec3,
    p: Vec3,
    v: Vec3,
    anchor: Vec3,
    law: [f64; 3],
    c_max: f64,
) -> Vec3 {
    let [kc, dc, mu] = law;
    let mut push = n * (kc * depth - dc * v.dot(n));
    if mu > 0.0 {
        push += crate::contact::friction::obstacle(p, v, depth, n, anchor, law, c_max);
    }
    if depth > 0.0 {
        push
    } else {
        Vec3::ZERO
    }
}

/// Depth (m) of the deepest penetration of any active point into a box wall, the plane or an
/// obstacle (0 if none), each point's clearance taken off (see [`crate::model::clearance`]: for
/// a body made from a mesh, how deep its skin went rather than its cage).
pub fn max_penetration(model: &Model, pos: &[Vec3]) -> f64 {
    let depth = |p: Vec3| {
        let wall = model.bounds.excursion(p);
        let plane = model
            .plane
            .and_then(|pl| pl.contact(p))
            .map_or(0.0, |c| c.depth);
        let obstacle = model
            .obstacles
            .iter()
            .filter_map(|o| o.contact(p))
            .map(|c| c.depth)
            .fold(0.0, f64::max);
        wall.max(plane).max(obstacle)
    };
    model
        .bodies()
        .iter()
        .flat_map(|body| {
            let first = body.points().start;
            (0..body.len())
                .filter(|&q| body.is_active(q))
                .map(move |q| depth(pos[first + q]) - model.clearance_of(first + q))
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Aabb;

    /// The kernel's branch-free wall force is the sum of the walls' contact forces.
    #[test]
    fn wall_force_is_the_sum_of_wall_contacts() {
        let b = Aabb::classic();
        let v = Vec3::new(0.3, -1.2, 2.5);
        for p in [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.5, 0.0, 0.0),
            Vec3::new(-2.25, 3.0, 0.5),
            Vec3::new(-3.0, -2.5, 2.125),
            Vec3::new(2.0, -2.0, 2.0),
        ] {
            let by_contacts = b
                .wall_contacts(p)
                .fold(Vec3::ZERO, |f, c| f + c.force(v, 400.0, 0.25));
            let by_axis = Vec3::new(
                wall_force(p.x, v.x, -2.0, 2.0, 400.0, 0.25),
                wall_force(p.y, v.y, -2.0, 2.0, 400.0, 0.25),
                wall_force(p.z, v.z, -2.0, 2.0, 400.0, 0.25),
            );
            assert_eq!(by_contacts, by_axis, "{p:?}");
            assert_eq!(
                b.wall_contacts(p).map(|c| c.depth).fold(0.0, f64::max),
                b.excursion(p)
            );
        }
    }
}
