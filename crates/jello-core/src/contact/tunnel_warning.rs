//! The warning for points that passed through an obstacle ([`Crossings`], found by
//! [`super::tunnelling::TunnelWatch`]), with a time step and a collision stiffness to try, named
//! as the reader sets them ([`Knobs`]: the command line's flags, Python's attributes). One
//! wording for `jello run` and the Python package, on the CPU and on a GPU.

use crate::contact::tunnelling::{Crossings, Sunk, Through};
use crate::model::obstacle::Obstacle;
use crate::model::Model;
use crate::vec3::significant;

/// How the advice names what to change, given the value to set (formatted).
#[derive(Clone, Copy, Debug)]
pub struct Knobs {
    /// The time step set to the value: `--dt 0.00025`, `sim.dt = 0.00025`.
    pub dt: fn(&str) -> String,
    /// Where the collision stiffness is set to the value: `` `[collision] stiffness` ``,
    /// `` `sim.set_collision(stiffness=2e5)` ``.
    pub stiffness: fn(&str) -> String,
}

/// A length (m) to 3 significant digits, in cm below a metre.
fn length(m: f64) -> String {
    if m.abs() < 1.0 {
        format!("{} cm", significant(m * 100.0, 3))
    } else {
        format!("{} m", significant(m, 3))
    }
}

/// What obstacle `o` is, for a message: `obstacle 2 (box, 5 cm thick there)`.
fn obstacle(model: &Model, o: usize, half_thickness: f64) -> String {
    let what = match model.obstacles[o] {
        Obstacle::Box(_) => format!("box, {} thick there", length(2.0 * half_thickness)),
        Obstacle::Sphere(s) => format!("ball of radius {}", length(s.radius)),
        Obstacle::Plane(_) => "plane".to_string(),
    };
    format!("obstacle {} ({what})", o + 1)
}

/// The warning for one body's crossings `c` of one obstacle, with what to try; `names` are the
/// bodies' names.
pub fn crossing_warning(model: &Model, c: &Crossings, names: &[String], knobs: &Knobs) -> String {
    let points = if c.points == 1 {
        "1 point".to_string()
    } else {
        format!("{} points", c.points)
    };
    // Every step compared with the last, or states read back several steps apart (a GPU's).
    let every_step = c.steps_apart <= 1;
    let steps = if c.steps == 1 {
        String::new()
    } else {
        format!(
            " (the first of {} {} that did, the last ending at t = {} s)",
            c.steps,
            if every_step { "steps" } else { "intervals" },
            significant(c.last.1, 6)
        )
    };
    // What to try: a shorter step when the points moved too far a step, a stiffer contact when
    // the penalty spring is too soft to stop them at the body's speed, or both.
    let stiffer = c.advised_stiffness(model).map(|k| {
        let k = significant(k, 2);
        format!(
            "a collision stiffness of at least {k} N/m ({})",
            (knobs.stiffness)(&k)
        )
    });
    let shorter = c.advised_dt().map(|dt| {
        format!(
            "{} or less (a step then moves them at most a quarter of the thickness)",
            (knobs.dt)(&significant(dt, 2))
        )
    });
    let advice = match (shorter, stiffer) {
        (Some(dt), Some(k)) => format!("try {dt}, with {k}"),
        (Some(dt), None) => format!("try {dt}"),
        (None, Some(k)) => format!("the step is short enough; try {k}"),
        // Slow points pushed through by the weight of the body behind them.
        (None, None) => format!(
            "the step is short enough and the contact stiff enough to stop a lone point at \
             that speed, so the body's weight pushes them through: try a collision stiffness \
             several times the present {} N/m",
            significant(model.k_collision, 3)
        ),
    };
    let (they, them) = if c.points == 1 {
        ("it", "it")
    } else {
        ("they", "them")
    };
    let (how, moved) = if every_step {
        (
            format!("a step carried {them}"),
            format!("a step moved {them} up to {}", length(c.longest_move)),
        )
    } else {
        (
            format!(
                "between states read back up to {} steps apart {they} went",
                c.steps_apart
            ),
            format!(
                "{they} moved up to {} between them, {} a step on average",
                length(c.longest_move),
                length(c.longest_move_a_step())
            ),
        )
    };
    format!(
        "{points} of body '{}' passed through {} between t = {} s and {} s{steps}: {how} past its \
         middle, {} from its faces, where the contact pushes {them} out of the far side ({moved}; \
         the body moved at up to {} m/s); {advice}",
        names[c.body],
        obstacle(model, c.obstacle, c.half_thickness),
        significant(c.first.0, 6),
        significant(c.first.1, 6),
        length(c.half_thickness),
        significant(c.impact_speed, 3),
    )
}

/// The warning for an obstacle through a body at the end of a run (`t`), when no point of the
/// body was seen passing through it; `names` are the bodies' names.
pub fn through_warning(model: &Model, t: &Through, names: &[String]) -> String {
    let edges = if t.edges == 1 {
        "1 edge of its lattice crosses".to_string()
    } else {
        format!("{} edges of its lattice cross", t.edges)
    };
    let why = if t.thinner_than_lattice() {
        format!(
            "the obstacle is thinner than the body's lattice spacing ({}), so it passes between \
             the body's points without touching them: try a finer lattice (a spacing under {}) \
             or a thicker obstacle",
            length(t.spacing),
            length(2.0 * t.half_thickness)
        )
    } else {
        "its points went past the obstacle's middle between the states compared".to_string()
    };
    format!(
        "body '{}' ends with {} through it: {edges} the obstacle's middle, {} from its faces, \
         where the contact pushes the two ends out on opposite sides; {why}",
        names[t.body],
        obstacle(model, t.obstacle, t.half_thickness),
        length(t.half_thickness),
    )
}

/// The warning for two bodies that end inside each other (`s`), with what to try; `names` are
/// the bodies' names.
pub fn sunk_warning(model: &Model, s: &Sunk, names: &[String], knobs: &Knobs) -> String {
    let k = significant(s.advised_stiffness(model), 2);
    format!(
        "bodies '{}' and '{}' end {} inside each other (at ({}, {}, {})), more than half the \
         finer of their cells ({}): a contact too soft for their weight, or a body thrown into \
         the other faster than the contact stops it within a step; try a collision stiffness of \
         about {k} N/m ({}), and for a fast body a shorter step",
        names[s.bodies[0]],
        names[s.bodies[1]],
        length(s.depth),
        significant(s.at.x, 3),
        significant(s.at.y, 3),
        significant(s.at.z, 3),
        length(s.spacing),
        (knobs.stiffness)(&k),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::obstacle::Aabb;
    use crate::model::ModelBuilder;
    use crate::vec3::Vec3;

    const PYTHONISH: Knobs = Knobs {
        dt: |v| format!("dt = {v}"),
        stiffness: |k| format!("stiffness({k})"),
    };

    /// Crossings of a 5 cm plate at 30 m/s, found in states `steps_apart` steps of 2 ms apart.
    fn crossings(steps_apart: u64) -> (Model, Crossings) {
        let plate = Aabb::new(Vec3::new(-1.0, -1.0, -0.05), Vec3::new(1.0, 1.0, 0.0)).unwrap();
        let model = ModelBuilder::new()
            .obstacle(Obstacle::Box(plate))
            .collision(1e6, 20.0)
            .build()
            .unwrap();
        let c = Crossings {
            body: 0,
            obstacle: 0,
            points: 9,
            steps: 2,
            first: (0.014, 0.016),
            last: (0.122, 0.124),
            longest_move: 0.06 * steps_apart as f64,
            impact_speed: 30.0,
            half_thickness: 0.025,
            dt: 0.002,
            steps_apart,
            point_mass: 0.01,
        };
        (model, c)
    }

    /// The advice names the knobs as given; states several steps apart are said to be, and the
    /// time step is advised from the move a step.
    #[test]
    fn the_warning_says_how_the_states_were_compared_and_names_the_knobs() {
        let names = ["cube".to_string()];
        let (model, every_step) = crossings(1);
        let text = crossing_warning(&model, &every_step, &names, &PYTHONISH);
        assert!(
            text.starts_with(
                "9 points of body 'cube' passed through obstacle 1 (box, 5 cm thick there) \
                 between t = 0.014 s and 0.016 s (the first of 2 steps that did, the last ending \
                 at t = 0.124 s): a step carried them past its middle, 2.5 cm from its faces"
            ),
            "{text}"
        );
        assert!(text.contains("try dt = 0.00042 or less"), "{text}");
        let (model, apart) = crossings(10);
        let text = crossing_warning(&model, &apart, &names, &PYTHONISH);
        assert!(
            text.contains(
                "(the first of 2 intervals that did, the last ending at t = 0.124 s): between \
                 states read back up to 10 steps apart they went past its middle"
            ),
            "{text}"
        );
        assert!(text.contains("they moved up to 60 cm between them, 6 cm a step on average"));
        assert!(text.contains("try dt = 0.00042 or less"), "{text}");
    }
}
