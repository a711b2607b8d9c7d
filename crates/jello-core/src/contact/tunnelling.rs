//! Tunnelling: points that a step carried through the middle of a solid obstacle, a diagnostic
//! read off two successive states, never part of stepping.
//!
//! The penalty law pushes a point inside a solid box out through its nearest face, and one
//! inside a ball out along its radius. A point that gets past the middle of the obstacle in one
//! step (it moved more than half the obstacle's thickness, or the penalty spring was too soft to
//! stop it in time) is then pushed out of the far side: it has passed through, and no state
//! shows it (the depth is measured to the nearest face, so it never exceeds half the thickness).
//! [`TunnelWatch`] compares each step's positions with the last step's and counts such points.
//!
//! What counts as a crossing:
//! - a solid box: the segment from a point's old position to its new one crosses the box's
//!   middle plane across some axis at a place inside the box where the faces across that axis
//!   are the nearest (so the push reverses there);
//! - a ball: the segment passes the centre (the old and new positions on opposite sides of it)
//!   more than half the radius deep.
//!
//! A point of a body made from a mesh that rests outside its skin is judged by where its skin
//! is: it counts only once it is its clearance past the middle (see [`crate::model::clearance`]:
//! the obstacle pushes it that much later, so its skin is about that far behind it).
//!
//! A state alone shows an obstacle through a body ([`obstacles_through`]): an edge of the body's
//! lattice (a structural spring) that crosses the obstacle's middle, as a step would, has its
//! ends pushed out on opposite sides. That is a body left impaled by points that passed through,
//! or one whose lattice is coarser than the obstacle, which then passes between its points
//! without any point touching it, which no watch of points sees.
//!
//! Planes, the classic plane and the box's walls are half-spaces: nothing passes through them
//! (the blow-up check catches a point far beyond a wall), so they are not watched.
//!
//! The watch goes over the bodies' active points in order on one thread: the same report on any
//! number of threads.
//!
//! States further apart than a step (a GPU's state, read back only now and then) are compared
//! the same way, by the straight segment between them
//! ([`TunnelWatch::observe_apart`]): a point that went through the obstacle between them, or
//! is past its middle at the second, is found; one that went around it in between could be
//! counted too, so the closer the states the better.

use crate::model::body::Body;
use crate::model::lattice::SpringKind;
use crate::model::obstacle::{Aabb, Obstacle, Sphere};
use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

/// The crossings of one body through one obstacle over the steps watched.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossings {
    /// The body (an index into the model's bodies).
    pub body: usize,
    /// The obstacle (an index into the model's obstacles).
    pub obstacle: usize,
    /// How many of the body's points crossed it (each counted once).
    pub points: usize,
    /// How many steps carried some point of the body across it.
    pub steps: u64,
    /// The first step that did: its start and end time (s).
    pub first: (f64, f64),
    /// The last step that did: its start and end time (s).
    pub last: (f64, f64),
    /// The longest move of a crossing point in its crossing step (m).
    pub longest_move: f64,
    /// The fastest the body's centre of mass moved over the steps watched up to the last
    /// crossing, or went in a state watched (m/s): the speed it may have hit the obstacle with.
    pub impact_speed: f64,
    /// Half the obstacle's thickness where it was crossed (m): half the box's size across the
    /// crossing axis, half a ball's radius.
    pub half_thickness: f64,
    /// The time step of the crossing steps (s).
    pub dt: f64,
    /// How many steps apart the states compared were where a crossing was found (the most): 1
    /// when every step was watched.
    pub steps_apart: u64,
    /// The mass of one of the body's points (kg).
    pub point_mass: f64,
}

impl Crossings {
    /// The longest a step should be (s) when a step moved points further than half of
    /// [`Crossings::half_thickness`] (`None` when none did): the CFL-like bound at which the
    /// crossing points, and the body's centre at its impact speed, move at most that far. With
    /// states several steps apart, a point's move a step is taken as its move between them
    /// shared evenly over the steps.
    pub fn advised_dt(&self) -> Option<f64> {
        let limit = 0.5 * self.half_thickness;
        let step = self.longest_move_a_step().max(self.impact_speed * self.dt);
        (step > limit).then(|| self.dt * limit / step)
    }

    /// [`Crossings::longest_move`] a step: over the steps between the states compared, shared
    /// evenly (a lower bound when they are several steps apart).
    pub fn longest_move_a_step(&self) -> f64 {
        self.longest_move / self.steps_apart.max(1) as f64
    }

    /// The least collision stiffness (N/m) whose penalty spring stops a lone point of the body
    /// at its impact speed within half of [`Crossings::half_thickness`] (a point of mass `m` at
    /// speed `v` on a spring `k` sinks `v·√(m/k)`); `None` when the stiffness is already that.
    /// A body's other points push behind it, so this is a lower bound.
    pub fn advised_stiffness(&self, model: &Model) -> Option<f64> {
        let stop = 0.5 * self.half_thickness;
        let k = self.point_mass * (self.impact_speed / stop).powi(2);
        (k > model.k_collision).then_some(k)
    }
}

/// Watches successive states for points that pass through a solid obstacle (see the module's
/// documentation).
#[derive(Clone, Debug)]
pub struct TunnelWatch {
    /// The positions of the last state observed.
    before: Vec<Vec3>,
    /// Its time (s).
    time: f64,
    /// Per body, the fastest its centre of mass moved between two states so far, or went in one
    /// (m/s): between states far apart its mean speed, so its velocity in them counts too.
    fastest: Vec<f64>,
    /// Per (point, obstacle), whether the point has crossed it: allocated at the first crossing.
    crossed: Vec<bool>,
    found: Vec<Crossings>,
}

impl TunnelWatch {
    /// A watch starting from `state`.
    pub fn new(model: &Model, state: &State) -> Self {
        TunnelWatch {
            before: state.pos.clone(),
            time: state.time,
            fastest: model
                .bodies()
                .iter()
                .map(|body| centre(body, &state.vel).length())
                .collect(),
            crossed: Vec::new(),
            found: Vec::new(),
        }
    }

    /// True when `model` has an obstacle a point could pass through (a box or a ball): when it
    /// has none, [`TunnelWatch::observe`] never finds anything.
    pub fn watches(model: &Model) -> bool {
        model
            .obstacles
            .iter()
            .any(|o| matches!(o, Obstacle::Box(_) | Obstacle::Sphere(_)))
    }

    /// Compares `state` (one step after the last observed) with the last observed, records
    /// the points that crossed an obstacle between them, and keeps its positions.
    pub fn observe(&mut self, model: &Model, state: &State) {
        self.observe_apart(model, state, 1);
    }

    /// [`TunnelWatch::observe`] for a state `steps` steps after the last observed (a GPU's
    /// state read back now and then): the segment between the two stands for each point's
    /// path. Nothing is compared when `steps` is 0.
    pub fn observe_apart(&mut self, model: &Model, state: &State, steps: u64) {
        if steps == 0 {
            return;
        }
        let (pos, time) = (&state.pos, state.time);
        let apart = time - self.time;
        let dt = apart / steps as f64;
        for (b, body) in model.bodies().iter().enumerate() {
            let first = body.points().start;
            let shift = centre(body, pos) - centre(body, &self.before);
            if apart > 0.0 {
                self.fastest[b] = self.fastest[b].max(shift.length() / apart);
            }
            self.fastest[b] = self.fastest[b].max(centre(body, &state.vel).length());
            for q in (0..body.len()).filter(|&q| body.is_active(q)) {
                let (a, z) = (self.before[first + q], pos[first + q]);
                let moved = (z - a).length();
                let clearance = model.clearance_of(first + q);
                for (o, obstacle) in model.obstacles.iter().enumerate() {
                    let half = match obstacle {
                        Obstacle::Box(bx) => box_crossing(bx, a, z, clearance),
                        Obstacle::Sphere(s) => ball_crossing(s, a, z, clearance),
                        Obstacle::Plane(_) => None,
                    };
                    if let Some(half_thickness) = half {
                        let crossing = Crossing {
                            body: b,
                            point: first + q,
                            obstacle: o,
                            half_thickness,
                            moved,
                        };
                        self.record(model, crossing, dt, steps, time);
                    }
                }
            }
        }
        self.before.copy_from_slice(pos);
        self.time = time;
    }

    /// Records `crossing`, found between the last state observed and the one at `time`, `steps`
    /// steps of `dt` later.
    fn record(&mut self, model: &Model, crossing: Crossing, dt: f64, steps: u64, time: f64) {
        let Crossing {
            body,
            point,
            obstacle,
            half_thickness,
            moved,
        } = crossing;
        let obstacles = model.obstacles.len();
        if self.crossed.is_empty() {
            self.crossed = vec![false; model.point_count() * obstacles];
        }
        let new_point = !std::mem::replace(&mut self.crossed[point * obstacles + obstacle], true);
        let step = (self.time, time);
        let fastest = self.fastest[body];
        match self
            .found
            .iter_mut()
            .find(|c| c.body == body && c.obstacle == obstacle)
        {
            Some(c) => {
                c.points += usize::from(new_point);
                if c.last != step {
                    c.steps += 1;
                    c.last = step;
                }
                c.longest_move = c.longest_move.max(moved);
                c.impact_speed = fastest;
                c.half_thickness = c.half_thickness.min(half_thickness);
                c.dt = dt;
                c.steps_apart = c.steps_apart.max(steps);
            }
            None => self.found.push(Crossings {
                body,
                obstacle,
                points: 1,
                steps: 1,
                first: step,
                last: step,
                longest_move: moved,
                impact_speed: fastest,
                half_thickness,
                dt,
                steps_apart: steps,
                point_mass: model.body(body).material.mass,
            }),
        }
    }

    /// The crossings found so far, per body and obstacle, in the order first found.
    pub fn crossings(&self) -> &[Crossings] {
        &self.found
    }
}

/// An obstacle through a body at a state, found by [`obstacles_through`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Through {
    /// The body (an index into the model's bodies).
    pub body: usize,
    /// The obstacle (an index into the model's obstacles).
    pub obstacle: usize,
    /// How many of the body's lattice edges (structural springs) cross the obstacle's middle.
    pub edges: usize,
    /// Half the obstacle's thickness where the first was found (m), as in
    /// [`Crossings::half_thickness`].
    pub half_thickness: f64,
    /// The body's lattice spacing (m, the finest across its axes).
    pub spacing: f64,
}

impl Through {
    /// Whether the obstacle is thinner there than the body's lattice spacing, so that it can
    /// pass between the body's points.
    pub fn thinner_than_lattice(&self) -> bool {
        2.0 * self.half_thickness < self.spacing
    }
}

/// The obstacles (boxes and balls) through the bodies at positions `pos`: per body and
/// obstacle, the body's lattice edges (its structural springs between active points) that
/// cross the obstacle's middle, as a step does in [`TunnelWatch`]; in the order of the bodies,
/// then the obstacles.
pub fn obstacles_through(model: &Model, pos: &[Vec3]) -> Vec<Through> {
    let mut found = Vec::new();
    if !TunnelWatch::watches(model) {
        return found;
    }
    for (b, body) in model.bodies().iter().enumerate() {
        let first = body.points().start;
        // Only the obstacles the body's bounding box meets (most often none: the springs are
        // not gone over).
        let (lo, hi) = (first..first + body.len())
            .filter(|&p| body.is_active(p - first))
            .fold(
                (
                    Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
                    -Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
                ),
                |(lo, hi), p| (lo.min(pos[p]), hi.max(pos[p])),
            );
        let meets = |min: Vec3, max: Vec3| {
            let (min, max, lo, hi) = (min.to_array(), max.to_array(), lo.to_array(), hi.to_array());
            (0..3).all(|k| min[k] <= hi[k] && lo[k] <= max[k])
        };
        let near: Vec<usize> = (0..model.obstacles.len())
            .filter(|&o| match &model.obstacles[o] {
                Obstacle::Box(bx) => meets(bx.min, bx.max),
                Obstacle::Sphere(s) => {
                    let r = Vec3::new(s.radius, s.radius, s.radius);
                    meets(s.centre - r, s.centre + r)
                }
                Obstacle::Plane(_) => false,
            })
            .collect();
        if near.is_empty() {
            continue;
        }
        let mut per_obstacle: Vec<Option<(usize, f64)>> = vec![None; model.obstacles.len()];
        body.for_each_spring(|spring| {
            if spring.kind != SpringKind::Structural {
                return;
            }
            // An edge with an end outside the body's skin may pass an obstacle that the skin
            // does not (a turned cage's corner through a plate the skin rests on): only edges
            // on or inside the skin tell.
            let outside = |q: usize| model.clearance_of(first + q) > 0.0;
            if outside(spring.a) || outside(spring.b) {
                return;
            }
            let (a, z) = (pos[first + spring.a], pos[first + spring.b]);
            for &o in &near {
                let half = match &model.obstacles[o] {
                    Obstacle::Box(bx) => box_crossing(bx, a, z, 0.0),
                    Obstacle::Sphere(s) => ball_crossing(s, a, z, 0.0),
                    Obstacle::Plane(_) => None,
                };
                if let Some(half) = half {
                    let entry = per_obstacle[o].get_or_insert((0, half));
                    entry.0 += 1;
                }
            }
        });
        for (o, entry) in per_obstacle.into_iter().enumerate() {
            if let Some((edges, half_thickness)) = entry {
                found.push(Through {
                    body: b,
                    obstacle: o,
                    edges,
                    half_thickness,
                    spacing: body.min_spacing(),
                });
            }
        }
    }
    found
}

/// How deep two bodies may be inside each other at the end of a run, as a share of the finer of
/// their cells, before it is news: resting bodies press into each other by their weight over
/// the contact's stiffness, millimetres at sensible stiffnesses (docs/scenes.md).
pub const SUNK_SHARE: f64 = 0.5;

/// Two bodies deeper inside each other than [`SUNK_SHARE`] of the finer of their cells, found by
/// [`bodies_sunk`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sunk {
    /// The bodies (indices into the model's bodies, the lower first).
    pub bodies: [usize; 2],
    /// How deep a surface point of one is inside the other, at the deepest (m).
    pub depth: f64,
    /// Where (m).
    pub at: Vec3,
    /// The finer of the two bodies' lattice spacings (m).
    pub spacing: f64,
}

impl Sunk {
    /// The collision stiffness (N/m, to two significant digits) that would hold the bodies 2 %
    /// of the finer cell into each other at rest: a penalty contact's depth at rest goes as one
    /// over its stiffness.
    pub fn advised_stiffness(&self, model: &Model) -> f64 {
        let k = model.k_collision * self.depth / (0.02 * self.spacing);
        crate::vec3::round_significant(k, 2)
    }
}

/// The pairs of bodies at positions `pos` whose surfaces are inside each other by more than
/// [`SUNK_SHARE`] of the finer of their cells (by [`crate::contact::closest`]): a body thrown into
/// another faster than the contact stops it within a step, or a contact too soft for the
/// bodies' weight. A body's surface inside itself (under self-contact) is not counted.
pub fn bodies_sunk(model: &Model, pos: &[Vec3]) -> Vec<Sunk> {
    sunk(model, pos)
        .filter(|s| s.bodies[0] != s.bodies[1])
        .collect()
}

/// Of the pairs of bodies at positions `pos` inside each other by more than [`SUNK_SHARE`] of
/// the finer of their cells, and (under self-contact) the bodies inside themselves by more than
/// that of a cell, the deepest (the first of equals): what a blow-up reports of the last state
/// before it, where a body crushed by its load or thrown through another set it off.
pub fn deepest_sunk(model: &Model, pos: &[Vec3]) -> Option<Sunk> {
    sunk(model, pos).fold(None, |deepest: Option<Sunk>, s| match deepest {
        Some(d) if d.depth >= s.depth => Some(d),
        _ => Some(s),
    })
}

/// Every pair of bodies (a body with itself under self-contact) inside each other by more
/// than [`SUNK_SHARE`] of the finer of their cells, in [`crate::contact::closest`]'s order.
fn sunk<'a>(model: &'a Model, pos: &[Vec3]) -> impl Iterator<Item = Sunk> + 'a {
    crate::contact::closest(model, pos)
        .into_iter()
        .filter_map(|c| {
            let [a, b] = c.bodies;
            let spacing = model.body(a).min_spacing().min(model.body(b).min_spacing());
            (c.depth > SUNK_SHARE * spacing).then_some(Sunk {
                bodies: c.bodies,
                depth: c.depth,
                at: c.at,
                spacing,
            })
        })
}

/// One point's crossing of one obstacle, as [`TunnelWatch::observe_apart`] finds it.
struct Crossing {
    body: usize,
    /// The point (an index into the model's arrays).
    point: usize,
    obstacle: usize,
    /// Half the obstacle's thickness where it was crossed (m).
    half_thickness: f64,
    /// How far the point moved between the two states (m).
    moved: f64,
}

/// The centre of `body`'s active points at positions `pos` (the model's arrays).
fn centre(body: &Body, pos: &[Vec3]) -> Vec3 {
    let first = body.points().start;
    let sum = (0..body.len())
        .filter(|&q| body.is_active(q))
        .fold(Vec3::ZERO, |s, q| s + pos[first + q]);
    sum / body.active_count().max(1) as f64
}

/// Half the box's size across the axis whose middle plane the segment `a`–`z` crosses inside
/// the box, where that axis's faces are the nearest; `None` when it crosses none. A point of
/// clearance `c` crosses the plane `c` past the middle from the side it starts on (none when
/// that is not inside the box).
fn box_crossing(bx: &Aabb, a: Vec3, z: Vec3, c: f64) -> Option<f64> {
    let (lo, hi) = (bx.min.to_array(), bx.max.to_array());
    let (a, z) = (a.to_array(), z.to_array());
    // Quick reject: the segment's bounding box misses the box.
    if (0..3).any(|k| a[k].max(z[k]) <= lo[k] || a[k].min(z[k]) >= hi[k]) {
        return None;
    }
    (0..3).find_map(|k| {
        let half = 0.5 * (hi[k] - lo[k]);
        if c >= half {
            return None;
        }
        // The point's skin is on the side it came from, `c` behind it.
        let middle = 0.5 * (lo[k] + hi[k]);
        let mid = middle + if a[k] > middle { -c } else { c };
        if (a[k] < mid) == (z[k] < mid) {
            return None;
        }
        let t = (mid - a[k]) / (z[k] - a[k]);
        // Where the segment crosses the middle plane: inside, with the other faces further.
        let deep_enough = (0..3).filter(|&j| j != k).all(|j| {
            let c = a[j] + t * (z[j] - a[j]);
            (c - lo[j]).min(hi[j] - c) >= half
        });
        deep_enough.then_some(half)
    })
}

/// Half the ball's radius when the segment `a`–`z` passes its centre more than half the radius
/// (plus the point's clearance `c`) deep; `None` otherwise.
fn ball_crossing(s: &Sphere, a: Vec3, z: Vec3, c: f64) -> Option<f64> {
    let (from, to) = (a - s.centre, z - s.centre);
    if from.dot(to) >= 0.0 {
        return None;
    }
    let d = to - from;
    let t = (-from.dot(d) / d.length_squared()).clamp(0.0, 1.0);
    let nearest = (from + d * t).length();
    let half = 0.5 * s.radius;
    (s.radius - nearest - c > half).then_some(half)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plate() -> Aabb {
        Aabb::new(Vec3::new(-1.0, -1.0, -0.05), Vec3::new(1.0, 1.0, 0.0)).unwrap()
    }

    /// A step from above a plate to below it, or from its upper half to its lower half, is a
    /// crossing; steps into the upper half, along it, or past its edge are not.
    #[test]
    fn a_plate_is_crossed_only_through_its_middle() {
        let p = plate();
        let at = |x: f64, z: f64| Vec3::new(x, 0.0, z);
        assert_eq!(
            box_crossing(&p, at(0.0, 0.01), at(0.0, -0.06), 0.0),
            Some(0.025)
        );
        assert_eq!(
            box_crossing(&p, at(0.3, -0.02), at(0.3, -0.03), 0.0),
            Some(0.025)
        );
        assert_eq!(box_crossing(&p, at(0.0, 0.01), at(0.0, -0.02), 0.0), None);
        assert_eq!(box_crossing(&p, at(0.0, -0.01), at(0.5, -0.02), 0.0), None);
        assert_eq!(box_crossing(&p, at(1.5, 0.01), at(1.5, -0.06), 0.0), None);
        // Through the very edge, where the side face is nearer than the middle: pushed out
        // sideways, not through.
        assert_eq!(box_crossing(&p, at(0.99, 0.01), at(0.99, -0.06), 0.0), None);
        // A point resting 1 cm outside its skin counts 1 cm past the middle from the side it
        // came from (its skin is behind it), however it moves about where it rests; one resting
        // further out than the plate's half thickness is never pushed back.
        assert_eq!(box_crossing(&p, at(0.0, -0.02), at(0.0, -0.03), 0.01), None);
        assert_eq!(
            box_crossing(&p, at(0.0, -0.02), at(0.0, -0.04), 0.01),
            Some(0.025)
        );
        assert_eq!(box_crossing(&p, at(0.0, -0.03), at(0.0, -0.02), 0.01), None);
        assert_eq!(
            box_crossing(&p, at(0.0, -0.017), at(0.0, -0.014), 0.01),
            None
        );
        assert_eq!(
            box_crossing(&p, at(0.0, -0.06), at(0.0, -0.01), 0.01),
            Some(0.025)
        );
        assert_eq!(box_crossing(&p, at(0.0, 0.01), at(0.0, -0.06), 0.03), None);
    }

    /// A body moved through a plate in one step is counted, each point once over the steps;
    /// a model with only a plane obstacle has nothing to watch.
    #[test]
    fn the_watch_counts_each_point_once_per_obstacle() {
        use crate::model::ModelBuilder;
        use crate::state::State;
        let plate = Aabb::new(Vec3::new(-1.0, -1.0, -0.55), Vec3::new(2.0, 2.0, -0.45)).unwrap();
        let far = Sphere::new(Vec3::new(5.0, 5.0, 5.0), 0.1).unwrap();
        let model = ModelBuilder::new()
            .obstacles(vec![Obstacle::Sphere(far), Obstacle::Box(plate)])
            .build()
            .unwrap();
        let at = |time: f64, drop: f64| {
            let mut s = State::at_rest(&model);
            s.pos.iter_mut().for_each(|p| p.z -= drop);
            s.time = time;
            s
        };
        let mut watch = TunnelWatch::new(&model, &at(0.0, 0.0));
        watch.observe(&model, &at(0.5, 0.0));
        assert!(watch.crossings().is_empty());
        watch.observe(&model, &at(1.0, 2.0));
        watch.observe(&model, &at(1.5, 0.0));
        let [c] = watch.crossings() else {
            panic!("{:?}", watch.crossings())
        };
        assert_eq!((c.body, c.obstacle, c.points, c.steps), (0, 1, 512, 2));
        assert_eq!((c.first, c.last), ((0.5, 1.0), (1.0, 1.5)));
        assert!((c.half_thickness - 0.05).abs() < 1e-12);
        // The body's centre moved 2 m in a step of 0.5 s, 4 m/s: a step that moves it a
        // quarter of the 10 cm plate's thickness is 0.025 m / 4 m/s.
        assert!((c.impact_speed - 4.0).abs() < 1e-9);
        assert!((c.advised_dt().unwrap() - 0.025 / 4.0).abs() < 1e-12);

        let plane = crate::model::obstacle::Plane::new([0.0, 0.0, 1.0, 0.5]).unwrap();
        let planar = ModelBuilder::new()
            .obstacle(Obstacle::Plane(plane))
            .build()
            .unwrap();
        assert!(!TunnelWatch::watches(&planar) && TunnelWatch::watches(&model));
    }

    /// States read back 10 steps apart: a body that went through a plate between them is
    /// counted, its advice taken from its move shared over the 10 steps; nothing is compared
    /// across no step.
    #[test]
    fn states_several_steps_apart_are_compared_by_the_segment_between_them() {
        use crate::model::ModelBuilder;
        use crate::state::State;
        let plate = Aabb::new(Vec3::new(-1.0, -1.0, -0.55), Vec3::new(2.0, 2.0, -0.45)).unwrap();
        let model = ModelBuilder::new()
            .obstacle(Obstacle::Box(plate))
            .build()
            .unwrap();
        let above = State::at_rest(&model);
        let mut below = above.clone();
        below.pos.iter_mut().for_each(|p| p.z -= 2.0);
        below.time = 1.0;
        let mut watch = TunnelWatch::new(&model, &above);
        watch.observe_apart(&model, &below, 0);
        assert!(watch.crossings().is_empty());
        watch.observe_apart(&model, &below, 10);
        let [c] = watch.crossings() else {
            panic!("{:?}", watch.crossings())
        };
        assert_eq!((c.points, c.steps, c.steps_apart), (512, 1, 10));
        assert_eq!(c.first, (0.0, 1.0));
        assert!((c.dt - 0.1).abs() < 1e-12 && (c.longest_move_a_step() - 0.2).abs() < 1e-12);
        // 2 m in 1 s, 0.2 m a step of 0.1 s: a step that moves it 0.025 m is 0.0125 s.
        assert!((c.advised_dt().unwrap() - 0.0125).abs() < 1e-12);

        // A body that went at 10 m/s in a state watched hit the plate at that speed, whatever
        // its mean speed between the states.
        let mut fast = above.clone();
        fast.vel.iter_mut().for_each(|v| v.z = -10.0);
        let mut watch = TunnelWatch::new(&model, &fast);
        watch.observe_apart(&model, &below, 10);
        assert!((watch.crossings()[0].impact_speed - 10.0).abs() < 1e-9);
    }

    /// A thin plate between two layers of the classic cube's points crosses the 64 edges
    /// between them; below the cube it crosses none.
    #[test]
    fn a_plate_between_two_layers_of_points_is_through_the_body() {
        use crate::model::ModelBuilder;
        use crate::state::State;
        let plate_at = |z: f64| {
            let plate = Aabb::new(
                Vec3::new(-5.0, -5.0, z - 0.01),
                Vec3::new(5.0, 5.0, z + 0.01),
            );
            ModelBuilder::new()
                .obstacle(Obstacle::Box(plate.unwrap()))
                .build()
                .unwrap()
        };
        let pos = State::at_rest(&plate_at(0.0)).pos;
        let mut zs: Vec<f64> = pos.iter().map(|p| p.z).collect();
        zs.sort_by(f64::total_cmp);
        zs.dedup();
        let between = 0.5 * (zs[3] + zs[4]);
        let [t] = obstacles_through(&plate_at(between), &pos)[..] else {
            panic!()
        };
        assert_eq!((t.body, t.obstacle, t.edges), (0, 0, 64));
        assert!((t.half_thickness - 0.01).abs() < 1e-12 && t.thinner_than_lattice());
        assert!(obstacles_through(&plate_at(zs[0] - 0.5), &pos).is_empty());
    }

    #[test]
    fn a_ball_is_crossed_only_past_its_centre_deep_inside() {
        let s = Sphere::new(Vec3::ZERO, 0.2).unwrap();
        let z = |x: f64, z: f64| Vec3::new(x, 0.0, z);
        assert_eq!(ball_crossing(&s, z(0.0, 0.3), z(0.0, -0.3), 0.0), Some(0.1));
        assert_eq!(
            ball_crossing(&s, z(0.05, 0.3), z(0.05, -0.3), 0.0),
            Some(0.1)
        );
        // Grazing past it, and sinking in without passing the centre.
        assert_eq!(ball_crossing(&s, z(0.15, 0.3), z(0.15, -0.3), 0.0), None);
        assert_eq!(ball_crossing(&s, z(0.0, 0.3), z(0.0, 0.05), 0.0), None);
        // A point resting 6 cm outside its skin: its skin passes 4 cm from the centre.
        assert_eq!(ball_crossing(&s, z(0.05, 0.3), z(0.05, -0.3), 0.06), None);
        assert_eq!(
            ball_crossing(&s, z(0.03, 0.3), z(0.03, -0.3), 0.06),
            Some(0.1)
        );
    }
}
