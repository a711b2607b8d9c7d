//! `jello run`'s warnings about bodies that passed through obstacles (see
//! `jello_core::contact::tunnelling`), with a time step and a collision stiffness to try.

use jello_core::diagnostics::Crossings;
use jello_core::vec3::significant;
use jello_core::{Model, Obstacle};

/// A length (m) to 3 significant digits, in cm below a metre.
fn length(m: f64) -> String {
    if m.abs() < 1.0 {
        format!("{} cm", significant(m * 100.0, 3))
    } else {
        format!("{} m", significant(m, 3))
    }
}

/// What obstacle `o` is, for a message: `obstacle 2 (box, 5 cm thick)`.
fn obstacle(model: &Model, o: usize, half_thickness: f64) -> String {
    let what = match model.obstacles[o] {
        Obstacle::Box(_) => format!("box, {} thick there", length(2.0 * half_thickness)),
        Obstacle::Sphere(s) => format!("ball of radius {}", length(s.radius)),
        Obstacle::Plane(_) => "plane".to_string(),
    };
    format!("obstacle {} ({what})", o + 1)
}

/// The warning for one body's crossings of one obstacle, with what to try.
pub(crate) fn crossing_warning(model: &Model, c: &Crossings, names: &[String]) -> String {
    let points = if c.points == 1 {
        "1 point".to_string()
    } else {
        format!("{} points", c.points)
    };
    let steps = if c.steps == 1 {
        String::new()
    } else {
        format!(
            " (the first of {} steps that did, the last ending at t = {} s)",
            c.steps,
            significant(c.last.1, 6)
        )
    };
    // What to try: a shorter step when the points moved too far a step, a stiffer contact when
    // the penalty spring is too soft to stop them at the body's speed, or both.
    let stiffer = c.advised_stiffness(model).map(|k| {
        format!(
            "a collision stiffness of at least {} N/m (`[collision] stiffness`, `jello create \
             --collision-stiffness`)",
            significant(k, 2)
        )
    });
    let shorter = c.advised_dt().map(|dt| {
        format!(
            "--dt {} or less (a step then moves them at most a quarter of the thickness)",
            significant(dt, 2)
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
    let them = if c.points == 1 { "it" } else { "them" };
    format!(
        "{points} of body '{}' passed through {} between t = {} s and {} s{steps}: a step \
         carried {them} past its middle, {} from its faces, where the contact pushes {them} out \
         of the far side (a step moved {them} up to {}; the body moved at up to {} m/s); {advice}",
        names[c.body],
        obstacle(model, c.obstacle, c.half_thickness),
        significant(c.first.0, 6),
        significant(c.first.1, 6),
        length(c.half_thickness),
        length(c.longest_move),
        significant(c.impact_speed, 3),
    )
}
