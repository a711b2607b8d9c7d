//! Backward Euler's step on the benchmark scene solved two ways, to the same tolerance, on the
//! same problems: Jello's Newton's method (conjugate gradients with a multigrid cycle, the
//! integrator itself) and Vertex Block Descent (Chen, Macklin et al. 2024: Gauss–Seidel sweeps
//! of a Newton step per point on the incremental potential, its own 3×3 block of the Hessian
//! with each spring's transverse stiffness clamped at zero), the method issue 9 named beside
//! Newton's and local/global iterations. The comparison and its figures: docs/implicit.md,
//! "Newton's method against vertex block descent".
//!
//! ```text
//! cargo run --release -p jello-core --example solver_comparison -- [N] [STEPS] [TOLERANCE]
//! ```
//!
//! Each of the first STEPS steps (default 60) of the N³ benchmark scene (default 16) at
//! dt = 1/60 s is taken by the integrator; vertex block descent then solves the same step from
//! the same start, from `v₀` plus the step's gravity, until every point's residual is within
//! the tolerance (default 1e-9 m/s, times the fastest point's speed above 1 m/s, as the
//! integrator judges it), or gives up after 20 000 sweeps. Block descent runs on one thread;
//! Newton's method runs on rayon's threads from 4 096 points, so pin the run to one core
//! (`taskset -c 1 cargo run …`, as for the figures in docs/implicit.md) to compare one thread
//! with one.

use std::time::Instant;

use jello_core::model::solver::Newton;
use jello_core::{benchmark, Integrator, Model, Simulation, Vec3};

const MAX_SWEEPS: usize = 20_000;

/// A spring seen from one of its ends: the other end, stiffness, damping and rest length.
#[derive(Clone, Copy)]
struct End {
    other: usize,
    k: f64,
    d: f64,
    rest: f64,
}

/// The springs of every point (compressed rows), with the model's other per-point terms.
struct Problem<'a> {
    model: &'a Model,
    starts: Vec<usize>,
    ends: Vec<End>,
    mass: Vec<f64>,
    h: f64,
}

impl<'a> Problem<'a> {
    fn new(model: &'a Model) -> Self {
        let n = model.point_count();
        let mut lists = vec![Vec::new(); n];
        let mut mass = vec![0.0; n];
        for body in model.bodies() {
            let first = body.points().start;
            mass[body.points()].fill(body.material.mass);
            body.for_each_spring(|s| {
                let (a, b) = (first + s.a, first + s.b);
                let (k, d, rest) = (s.stiffness, s.damping, s.rest);
                lists[a].push(End {
                    other: b,
                    k,
                    d,
                    rest,
                });
                lists[b].push(End {
                    other: a,
                    k,
                    d,
                    rest,
                });
            });
        }
        let mut starts = vec![0];
        let mut ends = Vec::new();
        for list in lists {
            ends.extend(list);
            starts.push(ends.len());
        }
        Problem {
            model,
            starts,
            ends,
            mass,
            h: model.dt,
        }
    }

    /// Point `i`'s part of the incremental potential's gradient (`M·g`, `g` the integrator's
    /// residual) at the velocities `v`, and its 3×3 block of the Hessian (row-major).
    fn local(&self, i: usize, x0: &[Vec3], v0: &[Vec3], v: &[Vec3]) -> (Vec3, [f64; 9]) {
        let (h, m, model) = (self.h, self.mass[i], self.model);
        let (kc, dc) = (model.k_collision, model.d_collision);
        let xi = x0[i] + v[i] * h;
        let mut grad = (v[i] - v0[i]) * m;
        let mut hess = [m, 0.0, 0.0, 0.0, m, 0.0, 0.0, 0.0, m];
        if let Some(field) = &model.field {
            grad -= field.sample(xi) * h;
        }
        grad -= model.gravity * (m * h);
        for c in model.contacts(xi) {
            grad -= c.normal * (h * kc * c.depth);
            add_outer(&mut hess, c.normal, h * h * kc);
        }
        // The dampers at the step's start, as the integrator takes them.
        for c in model.contacts(x0[i]) {
            grad += c.normal * (h * dc * c.normal.dot(v[i]));
            add_outer(&mut hess, c.normal, h * dc);
        }
        for e in &self.ends[self.starts[i]..self.starts[i + 1]] {
            let j = e.other;
            let d = x0[j] + v[j] * h - xi;
            let l = d.length();
            let u = d / l;
            grad -= u * (h * e.k * (l - e.rest));
            let transverse = (1.0 - e.rest / l).max(0.0);
            for r in 0..3 {
                hess[4 * r] += h * h * e.k * transverse;
            }
            add_outer(&mut hess, u, h * h * e.k * (1.0 - transverse));
            let d0 = x0[j] - x0[i];
            let u0 = d0 / d0.length();
            grad += u0 * (h * e.d * u0.dot(v[i] - v[j]));
            add_outer(&mut hess, u0, h * e.d);
        }
        (grad, hess)
    }

    /// The largest residual `|g|` of any point at `v`, and the integrator's bound for it.
    fn residual(&self, x0: &[Vec3], v0: &[Vec3], v: &[Vec3], tolerance: f64) -> (f64, f64) {
        let worst = (0..v.len())
            .map(|i| self.local(i, x0, v0, v).0.length() / self.mass[i])
            .fold(0.0, f64::max);
        let fastest = v.iter().map(|v| v.length()).fold(1.0, f64::max);
        (worst, tolerance * fastest)
    }

    /// Vertex block descent from `v` to the tolerance: the sweeps taken (`None`: not within
    /// [`MAX_SWEEPS`]).
    fn descend(&self, x0: &[Vec3], v0: &[Vec3], v: &mut [Vec3], tolerance: f64) -> Option<usize> {
        for sweep in 1..=MAX_SWEEPS {
            let mut worst: f64 = 0.0;
            for i in 0..v.len() {
                let (grad, hess) = self.local(i, x0, v0, v);
                worst = worst.max(grad.length() / self.mass[i]);
                v[i] -= solve(&hess, grad);
            }
            // The sweep's own residuals were taken before each point moved: confirm with a
            // pass that moves nothing.
            let fastest = v.iter().map(|v| v.length()).fold(1.0, f64::max);
            if worst <= tolerance * fastest {
                let (worst, bound) = self.residual(x0, v0, v, tolerance);
                if worst <= bound {
                    return Some(sweep);
                }
            }
        }
        None
    }
}

fn add_outer(m: &mut [f64; 9], u: Vec3, c: f64) {
    let u = [u.x, u.y, u.z];
    for r in 0..3 {
        for s in 0..3 {
            m[3 * r + s] += c * u[r] * u[s];
        }
    }
}

/// `m⁻¹·b` for a symmetric positive definite 3×3 `m` (by its cofactors).
fn solve(m: &[f64; 9], b: Vec3) -> Vec3 {
    let [a, b1, c, _, e, f, _, _, i] = *m;
    let (co0, co1, co2) = (e * i - f * f, c * f - b1 * i, b1 * f - c * e);
    let det = a * co0 + b1 * co1 + c * co2;
    let inv = [
        co0,
        co1,
        co2,
        co1,
        a * i - c * c,
        b1 * c - a * f,
        co2,
        b1 * c - a * f,
        a * e - b1 * b1,
    ];
    let row = |r: usize| (inv[3 * r] * b.x + inv[3 * r + 1] * b.y + inv[3 * r + 2] * b.z) / det;
    Vec3::new(row(0), row(1), row(2))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).map_or(default, String::as_str).to_owned();
    let n: usize = arg(0, "16").parse().expect("N: a lattice size");
    let steps: usize = arg(1, "60").parse().expect("STEPS: a step count");
    let tolerance: f64 = arg(2, "1e-9").parse().expect("TOLERANCE: m/s");
    let (model, state) = benchmark::scene(n, Integrator::BackwardEuler).expect("the scene");
    let newton = Newton {
        tolerance,
        ..Newton::default()
    };
    let model = (model.to_builder().dt(1.0 / 60.0).newton(newton).build()).expect("the model");
    let problem = Problem::new(&model);
    let mut sim = Simulation::new(model.clone(), state);
    let (mut newton_time, mut descent_time, mut sweeps, mut failed) = (0.0, 0.0, 0, 0);
    let mut largest_difference: f64 = 0.0;
    println!("{n}³ benchmark scene, dt 1/60 s, tolerance {tolerance:e} m/s, {steps} steps");
    println!("step  Newton (ms, iterations, CG)  descent (ms, sweeps)  |Δv| between them (m/s)");
    for step in 0..steps {
        let (x0, v0) = (sim.state.pos.clone(), sim.state.vel.clone());
        let before = sim.solver_stats();
        let start = Instant::now();
        sim.step()
            .expect("Newton's method converges on the benchmark");
        let newton_ms = start.elapsed().as_secs_f64() * 1e3;
        let after = sim.solver_stats();
        let mut v: Vec<Vec3> = (v0.iter()).map(|&v| v + model.gravity * model.dt).collect();
        if let Some(g) = model.field.as_ref().and_then(|f| f.uniform()) {
            v.iter_mut()
                .zip(&problem.mass)
                .for_each(|(v, &m)| *v += g * (model.dt / m));
        }
        let start = Instant::now();
        let taken = problem.descend(&x0, &v0, &mut v, tolerance);
        let descent_ms = start.elapsed().as_secs_f64() * 1e3;
        let difference = (v.iter().zip(&sim.state.vel))
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        newton_time += newton_ms;
        descent_time += descent_ms;
        match taken {
            Some(s) => {
                sweeps += s;
                largest_difference = largest_difference.max(difference);
            }
            None => failed += 1,
        }
        println!(
            "{step:4}  {newton_ms:8.2} {:3} {:5}  {descent_ms:10.1} {:>7}  {difference:.1e}",
            after.newton_iterations - before.newton_iterations,
            after.linear_iterations - before.linear_iterations,
            taken.map_or(format!(">{MAX_SWEEPS}"), |s| s.to_string()),
        );
    }
    let solved = steps - failed;
    println!(
        "Newton: {:.2} ms a step; vertex block descent: {:.1} ms a step, {:.0} sweeps a step \
         over the {solved} steps it solved ({failed} not within {MAX_SWEEPS} sweeps), {:.0}× \
         Newton's time; largest difference of the solutions {largest_difference:.1e} m/s",
        newton_time / steps as f64,
        descent_time / steps as f64,
        sweeps as f64 / solved.max(1) as f64,
        descent_time / newton_time,
    );
}
