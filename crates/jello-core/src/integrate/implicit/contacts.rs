//! The contacts' forces that depend on velocity, in an implicit step: the friction of obstacles
//! (each tie's spring and damper, or sliding friction where a point has no anchor yet) and of
//! contacts between bodies, at the iterate's positions and velocities, as the explicit
//! integrators take them (but for sliding friction's cap: [`friction::implicit_cap`]); and the dampers between bodies, along the directions of the pairs
//! that overlap at the step's start, as the walls', plane's and obstacles' dampers are taken
//! (`start_damping`: a damper that switches on at a surface with a jump can leave a step with no
//! solution). The force pass of the residual runs at zero velocities and without the ties
//! ([`Ties::Ignored`](crate::forces::Ties)), so these are all of the contacts' friction and
//! damping but the dampers along the walls', plane's and obstacles' normals. Their part of `A`
//! is assembled with the rest (`matrix.rs`).

use crate::compute::soa::Soa;
use crate::compute::team;
use crate::contact::bodies::Touch;
use crate::contact::cell_guard;
use crate::contact::friction::{self, anchored_surfaces, Anchors};
use crate::contact::Contacts;
use crate::model::Model;
use crate::vec3::Vec3;

/// How far outside another body (times the largest of the bodies' cells) a sample is held to it
/// through a step: the most a sample is expected to close in on a surface within one step.
const MARGIN: f64 = 0.5;

/// The touches a step holds its contacts between bodies to, found at its start `x` (in
/// `x_soa`): every sample of a body inside another, or less than [`MARGIN`] cells outside it,
/// with its depth then (negative: the gap), the other body's outward normal and the weights of
/// the points the force goes to (see [`Contacts::near`]).
pub(super) fn start_touches(
    model: &Model,
    contacts: &mut Contacts,
    x_soa: &Soa,
    touches: &mut Vec<Touch>,
) {
    touches.clear();
    if !model.surfaces_touch() {
        return;
    }
    let cell = model
        .bodies()
        .iter()
        .map(|b| b.min_spacing())
        .fold(0.0, f64::max);
    contacts.near(model, x_soa, MARGIN * cell, touches);
}

/// A touch's depth (m) at positions `x`, from its depth where it was found, at `x0`: the
/// sample's displacement into the other body along the normal it had then.
#[inline]
fn depth_at(t: &Touch, x: impl Fn(usize) -> Vec3, x0: &[Vec3]) -> f64 {
    let moved = (t.points.iter().zip(&t.weights)).fold(Vec3::ZERO, |s, (&p, &w)| {
        s + (x(p as usize) - x0[p as usize]) * w
    });
    t.depth - t.normal.dot(moved)
}

/// The contacts between bodies in an implicit step, at the touches found at its start: for each,
/// the penalty spring along the normal it had then, `kCollision·depth`, with the depth followed
/// linearly from there (so that the residual is smooth in the iterate and its derivative is
/// `A`'s block, `h²·kCollision·nnᵀ`, on the sample's displacement relative to the other body;
/// a touch whose depth falls to 0 lets go), its sliding friction at the iterate's velocities,
/// and, where it touched at the start, its damper along that normal. As `force`.
#[allow(clippy::too_many_arguments)]
fn add_touches(
    model: &Model,
    touches: &[Touch],
    x: impl Fn(usize) -> Vec3,
    x0: &[Vec3],
    v: &[Vec3],
    free: &[f64],
    force: &mut [Vec3],
) {
    let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
    for t in touches {
        let depth = depth_at(t, &x, x0);
        let w = t.relative(|q| v[q]);
        let n = t.normal;
        let mut f = Vec3::ZERO;
        if depth > 0.0 {
            f += n * (kc * depth);
            if mu > 0.0 {
                let c_max = friction::implicit_cap(t.reduced, model.dt, kc);
                f += friction::sliding(n, w, mu * kc * depth, c_max);
            }
        }
        if t.depth > 0.0 {
            f -= n * (dc * n.dot(w));
        }
        spread(&t.points, &t.weights, f, free, force);
    }
}

/// Adds `f`, the force on a touch's sample, to `force` at its points by their weights (minus
/// it at the other body's), where they move (`free`).
fn spread(points: &[u32; 16], weights: &[f64; 16], f: Vec3, free: &[f64], force: &mut [Vec3]) {
    for (&p, &w) in points.iter().zip(weights) {
        let p = p as usize;
        if free[p] != 0.0 {
            force[p] += f * w;
        }
    }
}

/// What the residual's force pass leaves out, added to `force` (N per point): friction at the
/// positions `x_soa` and velocities `v`, the contacts between bodies at `touches` (found with
/// the points at `x0`), and under self-contact the cells' guard at `x_soa`. `mass` per point
/// (kg), `free` 1 for a moving point (0: nothing is added to it).
#[allow(clippy::too_many_arguments)]
pub(super) fn add_forces(
    model: &Model,
    anchors: &Anchors,
    touches: &[Touch],
    x_soa: &Soa,
    x0: &[Vec3],
    v: &[Vec3],
    mass: &[f64],
    free: &[f64],
    force: &mut [Vec3],
) {
    let kc = model.k_collision;
    let dc = model.d_collision;
    let (px, py, pz) = (x_soa.x(), x_soa.y(), x_soa.z());
    let at = |i: usize| Vec3::new(px[i], py[i], pz[i]);
    if anchored_surfaces(model).next().is_some() {
        // Each point's friction is its own: the points in chunks over the team, and a chunk
        // surface by surface (each point's friction still added in the surfaces' order). A wall
        // is asked only about a chunk with a point past it, and a plane only about a point on
        // its forbidden side: asking every surface about every point was a tenth of a resting
        // 32³ cube's step on one thread.
        let size = super::chunk_size(force.len());
        team::for_each_chunk([force], size, &|chunk, [force]| {
            let points = chunk * size..chunk * size + force.len();
            let xyz = [&px[points.clone()], &py[points.clone()], &pz[points]];
            for surface in anchored_surfaces(model).filter(|s| s.may_touch_any(model, xyz)) {
                let law = [kc, dc, surface.friction(model)];
                for (j, f) in force.iter_mut().enumerate() {
                    let i = chunk * size + j;
                    let p = at(i);
                    if free[i] == 0.0 || !surface.may_touch(model, p) {
                        continue;
                    }
                    if let Some(c) = surface.contact_of(model, i, p) {
                        let anchor = anchors.anchor(surface, i);
                        let c_max = friction::implicit_cap(mass[i], model.dt, kc);
                        *f += friction::obstacle(p, v[i], c.depth, c.normal, anchor, law, c_max);
                    }
                }
            }
        });
    }
    add_touches(model, touches, at, x0, v, free, force);
    cell_guard::for_each_squeezed(model, at, |s| {
        for (p, f) in s.forces().filter(|&(p, _)| free[p] != 0.0) {
            force[p] += f;
        }
    });
}

/// A touch's part of `A` at positions `x` and velocities `v` (step `h`): the penalty spring's
/// `h²·kCollision·nnᵀ` and its friction's while it is in, the damper's `h·dCollision·nnᵀ` where it
/// touched at the start; `None` when it has none.
pub(super) fn touch_block(
    model: &Model,
    t: &Touch,
    x: impl Fn(usize) -> Vec3,
    x0: &[Vec3],
    v: &[Vec3],
    h: f64,
) -> Option<super::sym::Sym> {
    let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
    let depth = depth_at(t, x, x0);
    let n = t.normal;
    let mut block = [0.0; 6];
    let mut any = false;
    if depth > 0.0 {
        super::sym::add_outer(&mut block, n, h * h * kc);
        if mu > 0.0 {
            let c_max = friction::implicit_cap(t.reduced, model.dt, kc);
            let w = t.relative(|q| v[q]);
            let tangent = friction::sliding_tangent(n, w, mu * kc * depth, c_max, h);
            super::matrix::add_tangent(&mut block, n, tangent);
        }
        any = true;
    }
    if t.depth > 0.0 && dc > 0.0 {
        super::sym::add_outer(&mut block, n, h * dc);
        any = true;
    }
    any.then_some(block)
}

#[cfg(test)]
mod tests {
    use super::super::cg::apply_to;
    use super::super::matrix::{assemble, Curvature};
    use super::super::residual::residual;
    use super::super::stencil::Precision;
    use super::super::test_models::values;
    use super::super::ImplicitScratch;
    use crate::contact::friction::{self, Surface};
    use crate::forces::ForceScratch;
    use crate::model::body::{Body, Material, IDENTITY};
    use crate::model::lattice::Lattice;
    use crate::model::obstacle::{Obstacle, Plane};
    use crate::model::{Aabb, Model, ModelBuilder};
    use crate::state::{Control, State};
    use crate::vec3::Vec3;

    const H: f64 = 1.0 / 60.0;

    /// A box of `points` lattice points, unit spacing, 0.5 kg a point, first corner at `at`.
    fn heavy_box(points: [usize; 3], at: Vec3) -> Body {
        let size = points.map(|n| (n - 1) as f64);
        let material = Material {
            mass: 0.5,
            stiffness: [200.0; 3],
            damping: [0.5; 3],
        };
        let size = Vec3::new(size[0], size[1], size[2]);
        Body::lattice_box(Lattice::new(points, size), material).placed(at, IDENTITY)
    }

    fn far() -> Aabb {
        Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap()
    }

    /// `A·d` (with `A` assembled at the iterate `v`, and friction's growth with depth in it)
    /// and the central difference of `M·g` along `d` there, for the free points, and the
    /// largest entry of `A·d`.
    fn derivative(
        model: &Model,
        force: &mut ForceScratch,
        x0: &[Vec3],
        v: &[Vec3],
        d: &[Vec3],
    ) -> (Vec<Vec3>, Vec<Vec3>, f64) {
        let (ad, difference, scale, _) = derivatives(model, force, x0, v, d);
        (ad, difference, scale)
    }

    /// [`derivative`]'s, and `A·d` without friction's growth with depth.
    fn derivatives(
        model: &Model,
        force: &mut ForceScratch,
        x0: &[Vec3],
        v: &[Vec3],
        d: &[Vec3],
    ) -> (Vec<Vec3>, Vec<Vec3>, f64, Vec<Vec3>) {
        let control = Control::none();
        let mut s = ImplicitScratch::new(model);
        s.load(model);
        s.start_dampers(model, x0);
        let mut m_g = |s: &mut ImplicitScratch, v: &[Vec3]| {
            s.v.copy_from_slice(v);
            residual(model, &control, force, s, x0, x0, H, false);
            (s.g.iter().zip(&s.mass).zip(&s.free))
                .map(|((&g, &m), &free)| g * (m * free))
                .collect::<Vec<_>>()
        };
        let eps = 1e-6;
        let along = |sign: f64| -> Vec<Vec3> {
            v.iter()
                .zip(d)
                .map(|(&v, &d)| v + d * (sign * eps))
                .collect()
        };
        let (up, down) = (m_g(&mut s, &along(1.0)), m_g(&mut s, &along(-1.0)));
        let difference = up
            .iter()
            .zip(&down)
            .map(|(&u, &w)| (u - w) / (2.0 * eps))
            .collect();
        m_g(&mut s, v);
        let shift = Curvature::True { shift: 0.0 };
        assemble(model, &control, force.anchors(), &mut s, x0, H, shift);
        let mut ad = vec![Vec3::ZERO; d.len()];
        let (rows, blocks) = (&s.pair_rows[..], &s.pair_blocks[..]);
        let free = &s.free[..];
        let growth = &s.friction_growth[..];
        apply_to(
            &mut s.springs,
            free,
            rows,
            blocks,
            (None, growth),
            d,
            &mut ad,
            Precision::Double,
        );
        let mut symmetric = vec![Vec3::ZERO; d.len()];
        let no_growth = (None, &[][..]);
        let (springs, out) = (&mut s.springs, &mut symmetric);
        apply_to(
            springs,
            free,
            rows,
            blocks,
            no_growth,
            d,
            out,
            Precision::Double,
        );
        let scale = ad.iter().map(|a| a.max_abs()).fold(0.0, f64::max);
        (ad, difference, scale, symmetric)
    }

    fn assert_close(ad: &[Vec3], difference: &[Vec3], scale: f64) {
        for (p, (&a, &f)) in ad.iter().zip(difference).enumerate() {
            assert!(
                (a - f).max_abs() <= 1e-6 * scale,
                "point {p}: A·d {a:?}, difference {f:?}"
            );
        }
    }

    /// `A` is the derivative of `M·g` (the residual times the masses) with the friction of an
    /// obstacle, of the box's bottom wall and of the inclined plane, each the floor in turn:
    /// ties that hold and ties that slide, points with no anchor yet whose friction is at its
    /// cap or at its full size, each with its damper across the floor's normal; along
    /// directions in the floor where a point touches it, and along any direction with the
    /// friction limit's growth with depth (`friction_growth`), which the symmetric part alone
    /// misses.
    #[test]
    fn a_with_obstacle_friction_is_the_derivative_of_the_residual() {
        let floor = Plane::facing([0.0, 0.0, 1.0, 0.0], Vec3::new(0.0, 0.0, 1.0)).unwrap();
        let bottom = Aabb::new(Vec3::new(-50.0, -50.0, 0.0), Vec3::new(50.0, 50.0, 50.0)).unwrap();
        let builder = || {
            ModelBuilder::new()
                .bodies(vec![heavy_box([5, 4, 2], Vec3::new(0.0, 0.0, -0.05))])
                .collision(2000.0, 5.0)
                .gravity(Vec3::new(0.0, 0.0, -9.81))
                .dt(H)
        };
        let floors = [
            (
                builder()
                    .bounds(far())
                    .obstacle(Obstacle::Plane(floor))
                    .friction(0.5),
                Surface::Obstacle(0),
            ),
            (
                builder().bounds(bottom).wall_friction(0.5),
                Surface::Wall(4),
            ),
            (
                builder()
                    .bounds(far())
                    .plane(Some(floor))
                    .wall_friction(0.5),
                Surface::Plane,
            ),
        ];
        for (model, surface) in floors {
            friction_is_the_derivative(&model.build().unwrap(), surface);
        }
    }

    fn friction_is_the_derivative(model: &Model, surface: Surface) {
        let model = model.clone();
        let mut next = values(5);
        let mut random = || Vec3::new(next(), next(), next());
        let rest = State::at_rest(&model).pos;
        let touches = |p: Vec3| p.z < 0.0;
        let across = |a: Vec3, p: Vec3| {
            if touches(p) {
                Vec3::new(a.x, a.y, 0.0)
            } else {
                a
            }
        };
        // Every third point on the floor has no anchor (it was off the floor when they were
        // tied); the others are tied 0 to 2 cm from where they are.
        let tied: Vec<Vec3> = (rest.iter().enumerate())
            .map(|(i, &p)| match (touches(p), i % 3) {
                (true, 0) => p + Vec3::new(0.0, 0.0, 1.0),
                _ => p + across(random(), p) * 0.02,
            })
            .collect();
        let mut force = ForceScratch::new(&model);
        force.update_anchors(&model, &tied);
        let x0: Vec<Vec3> = rest
            .iter()
            .map(|&p| p + across(random(), p) * 0.01)
            .collect();
        // Speeds of 0.5 or 4 m/s across the floor, so that both of friction's regimes occur.
        let v: Vec<Vec3> = (x0.iter().enumerate())
            .map(|(i, &p)| across(random(), p) * if i % 5 < 2 { 0.5 } else { 4.0 })
            .collect();
        let d: Vec<Vec3> = x0.iter().map(|&p| across(random(), p)).collect();
        let mut regimes = [0; 4];
        for (i, (&x, &v)) in x0.iter().zip(&v).enumerate() {
            let p = x + v * H;
            let Some(c) = surface.contact(&model, p) else {
                continue;
            };
            let anchor = force.anchors().anchor(surface, i);
            let law = [
                model.k_collision,
                model.d_collision,
                surface.friction(&model),
            ];
            let c_max = friction::implicit_cap(0.5, H, model.k_collision);
            let (_, along) =
                friction::obstacle_tangent(p, v, c.depth, c.normal, anchor, law, c_max, H);
            regimes[2 * anchor.x.is_nan() as usize + along.is_some() as usize] += 1;
        }
        assert!(
            regimes.iter().all(|&n| n > 0),
            "{surface:?}: holding, sliding, capped, uncapped: {regimes:?}"
        );
        let (ad, difference, scale) = derivative(&model, &mut force, &x0, &v, &d);
        assert_close(&ad, &difference, scale);
        // Into the floor and out of it too: the friction that slides at its full size grows
        // with the depth.
        let d: Vec<Vec3> = x0.iter().map(|_| random()).collect();
        let (ad, difference, scale, symmetric) = derivatives(&model, &mut force, &x0, &v, &d);
        assert_close(&ad, &difference, scale);
        let missed = (symmetric.iter().zip(&difference))
            .map(|(&a, &f)| (a - f).max_abs())
            .fold(0.0, f64::max);
        assert!(
            missed > 1e-3 * scale,
            "{surface:?}: the symmetric part alone misses the growth by {missed:e} only"
        );
    }

    /// `A` is the derivative of `M·g` with contacts between bodies, held to the touches found at
    /// the step's start: their penalty springs along the normals they had then (the depth
    /// followed linearly), and their dampers; each alone (the other's coefficient too small to
    /// count), for bodies overlapping by a hundredth of a cell, moved rigidly.
    #[test]
    fn a_with_contacts_between_bodies_is_the_derivative_of_the_residual() {
        let bodies = || {
            vec![
                heavy_box([3, 3, 3], Vec3::ZERO),
                heavy_box([3, 4, 3], Vec3::new(1.99, 0.4, 0.3)),
            ]
        };
        let mut next = values(9);
        let mut random = || Vec3::new(next(), next(), next());
        let (first, second) = (random() * 0.2, random() * 0.2);
        let (d_first, d_second) = (random(), random());
        for (kc, dc, tolerance) in [(1e-9, 50.0, 1e-6), (2000.0, 1e-9, 1e-6)] {
            let model = ModelBuilder::new()
                .bodies(bodies())
                .bounds(far())
                .collision(kc, dc)
                .pins([4])
                .dt(H)
                .build()
                .unwrap();
            let x0 = State::at_rest(&model).pos;
            let split = model.body(1).points().start;
            let rigid = |a: Vec3, b: Vec3| -> Vec<Vec3> {
                (0..x0.len())
                    .map(|i| if i < split { a } else { b })
                    .collect()
            };
            let (v, d) = (rigid(first, second), rigid(d_first, d_second));
            let mut force = ForceScratch::new(&model);
            let (ad, difference, scale) = derivative(&model, &mut force, &x0, &v, &d);
            for (p, (&a, &f)) in ad.iter().zip(&difference).enumerate() {
                assert!(
                    (a - f).max_abs() <= tolerance * scale,
                    "kCollision {kc}, point {p}: A·d {a:?}, difference {f:?}"
                );
            }
            if dc > 1.0 {
                let mut s = ImplicitScratch::new(&model);
                s.load(&model);
                s.start_dampers(&model, &x0);
                let touches = s.start_touches.len();
                assert!(touches >= 4, "{touches} touches");
                // The dampers matter: without them `A·d` misses by far more.
                let undamped = model.to_builder().collision(kc, 0.0).build().unwrap();
                let (ad, _, _) = derivative(&undamped, &mut force, &x0, &v, &d);
                let worst = (ad.iter().zip(&difference))
                    .map(|(&a, &f)| (a - f).max_abs())
                    .fold(0.0, f64::max);
                assert!(worst > 1e-3 * scale, "{worst} against {scale}");
            }
        }
    }
}
