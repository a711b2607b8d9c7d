//! The one force routine: springs, force field, box and plane penalties, control forces.

use crate::model::Model;
use crate::state::Control;
use crate::vec3::Vec3;

/// Acceleration of every point (m/s²) at positions `pos` and velocities `vel`, written to `acc`.
///
/// All slices have the model's point count. Total force over mass, where the force on a point is
/// (SPEC.md): the sum of its spring forces, plus the interpolated force field, plus one penalty
/// spring per box wall it is strictly outside of, plus the plane penalty when it is on the
/// forbidden side, plus the control force.
pub fn accelerations(
    model: &Model,
    pos: &[Vec3],
    vel: &[Vec3],
    control: &Control,
    acc: &mut [Vec3],
) {
    let n = model.point_count();
    debug_assert!(pos.len() == n && vel.len() == n && acc.len() == n);
    assert!(
        control.forces.is_empty() || control.forces.len() == n,
        "control forces must be empty or one per point"
    );

    // Springs: one evaluation each, the force on A and its opposite on B (Newton's third law).
    acc.fill(Vec3::ZERO);
    let s = &model.springs;
    for ((&a, &b), (&rest, &kind)) in s.a.iter().zip(&s.b).zip(s.rest_len.iter().zip(&s.kind)) {
        let (a, b) = (a as usize, b as usize);
        let l = pos[a] - pos[b];
        let len = l.length();
        // A zero-length spring has no direction: it exerts no force rather than a NaN.
        if len == 0.0 {
            continue;
        }
        let dir = l / len;
        let k = model.stiffness[kind as usize];
        let d = model.damping[kind as usize];
        let f = dir * (-k * (len - rest)) - dir * (d * (vel[a] - vel[b]).dot(dir));
        acc[a] += f;
        acc[b] -= f;
    }

    // Per point: external forces, then divide by the mass.
    for p in 0..n {
        let mut f = acc[p];
        if let Some(field) = &model.field {
            f += field.sample(pos[p]);
        }
        f += wall_force(model, pos[p], vel[p]);
        if let Some(plane) = &model.plane {
            if let Some((depth, normal)) = plane.penetration(pos[p]) {
                f += penalty(model, depth, normal, vel[p]);
            }
        }
        if !control.forces.is_empty() {
            f += control.forces[p];
        }
        acc[p] = f / model.mass;
    }
}

/// Zero-rest-length penalty spring toward a wall or plane: `kCollision·depth·n − dCollision (v·n) n`.
#[inline]
fn penalty(model: &Model, depth: f64, normal: Vec3, v: Vec3) -> Vec3 {
    normal * (model.k_collision * depth) - normal * (model.d_collision * v.dot(normal))
}

/// Sum of the penalty springs of every box wall `p` is strictly outside of.
#[inline]
fn wall_force(model: &Model, p: Vec3, v: Vec3) -> Vec3 {
    let b = &model.bounds;
    let mut f = Vec3::ZERO;
    let axes = [
        (p.x, b.min.x, b.max.x, Vec3::new(1.0, 0.0, 0.0)),
        (p.y, b.min.y, b.max.y, Vec3::new(0.0, 1.0, 0.0)),
        (p.z, b.min.z, b.max.z, Vec3::new(0.0, 0.0, 1.0)),
    ];
    for (c, lo, hi, axis) in axes {
        if c < lo {
            f += penalty(model, lo - c, axis, v);
        } else if c > hi {
            f += penalty(model, c - hi, -axis, v);
        }
    }
    f
}

/// Depth (m) of the deepest penetration of any point into a box wall or the plane (0 if none).
pub fn max_penetration(model: &Model, pos: &[Vec3]) -> f64 {
    pos.iter()
        .map(|&p| {
            let wall = model.bounds.excursion(p);
            let plane = model
                .plane
                .and_then(|pl| pl.penetration(p))
                .map_or(0.0, |(depth, _)| depth);
            wall.max(plane)
        })
        .fold(0.0, f64::max)
}
