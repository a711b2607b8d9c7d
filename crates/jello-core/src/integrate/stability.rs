//! An estimate of the largest stable time step of each integrator for a model.
//!
//! Method (documented for users in docs/cli.md, "The stable time step"):
//! 1. Find the stiffest mode: the largest eigenvalue `Ω²` of the spring stiffness matrix over the
//!    mass, at the rest shape (power iteration; never above Gershgorin's bound `2·max_p Σ k / m`,
//!    the sum over the springs at point `p`). The damping matrix has the same structure and gives
//!    the rate `Γ`. With one ratio d/k for all springs the two share their modes.
//! 2. Model every mode as a damped oscillator `x'' = −ω² x − γ x'` with damping proportional to
//!    stiffness, `(ω², γ) = s·(Ω², Γ)` for `s` in `(0, 1]`; and, for a point pressed into a wall,
//!    the same plus one collision spring, `(s·Ω² + kCollision/m, s·Γ + dCollision/m)`.
//! 3. For each integrator, step that scalar oscillator exactly as [`crate::step()`] does, which gives
//!    its 2×2 amplification matrix, and find the largest `dt` for which every sampled mode has a
//!    spectral radius of at most 1.
//!
//! It is an estimate: the bound is conservative for the stiffness, the lattice is nonlinear, and
//! large deformations change the modes. Explicit Euler is unstable for an undamped oscillator at
//! every step size; with proportional damping its limit is about `d/k` whatever the mass.

use crate::integrate::implicit::{SDIRK2_C, SDIRK2_GAMMA};
use crate::model::body::Body;
use crate::model::integrator::Integrator;
use crate::model::Model;
use crate::vec3::Vec3;

/// Largest eigenvalue, over the mass, of the stiffness matrix (`tangent` true) or the damping
/// matrix (`tangent` false) of the springs at positions `pos`, each weighted by its stiffness or
/// damping `w`.
///
/// A spring's 3×3 block is `w ûûᵀ` for damping and `w (ûûᵀ + (1 − R/l)(I − ûûᵀ))` for stiffness:
/// at the rest shape the second term vanishes, but a spring stretched or crushed far from its rest
/// length is stiffer across its axis. Power iteration from a checkerboard start (close to the
/// stiffest lattice mode), capped by the Gershgorin bound `2·max_p Σ |block|`; lattices with more
/// than [`POWER_ITERATION_MAX_SPRINGS`] springs use the bound alone. The Rayleigh quotient
/// approaches from below, so it is raised by 2 %.
fn largest_eigenvalue(body: &Body, pos: &[Vec3], tangent: bool) -> f64 {
    let n = body.len();
    let s = &body.springs();
    let mass = body.material.mass;
    // Per spring: unit direction, axial weight and transverse weight.
    let blocks: Vec<(Vec3, f64, f64)> =
        s.a.iter()
            .zip(&s.b)
            .zip(
                s.rest_len
                    .iter()
                    .zip(if tangent { &s.stiffness } else { &s.damping }),
            )
            .map(|((&a, &b), (&rest, &w))| {
                let d = pos[a as usize] - pos[b as usize];
                let l = d.length();
                if l == 0.0 {
                    return (Vec3::ZERO, 0.0, 0.0);
                }
                let transverse = if tangent { w * (1.0 - rest / l) } else { 0.0 };
                (d / l, w, transverse)
            })
            .collect();
    let mut sum = vec![0.0; n];
    for ((&a, &b), &(_, w, t)) in s.a.iter().zip(&s.b).zip(&blocks) {
        let norm = w.max(t.abs());
        sum[a as usize] += norm;
        sum[b as usize] += norm;
    }
    let gershgorin = 2.0 * sum.iter().copied().fold(0.0, f64::max) / mass;
    if s.len() > POWER_ITERATION_MAX_SPRINGS || gershgorin == 0.0 {
        return gershgorin;
    }
    let apply = |x: &[Vec3], y: &mut [Vec3]| {
        y.fill(Vec3::ZERO);
        for ((&a, &b), &(u, w, t)) in s.a.iter().zip(&s.b).zip(&blocks) {
            let dx = x[a as usize] - x[b as usize];
            let axial = u * u.dot(dx);
            let f = axial * w + (dx - axial) * t;
            y[a as usize] += f;
            y[b as usize] -= f;
        }
    };
    let mut x: Vec<Vec3> = (0..n)
        .map(|p| {
            let [i, j, k] = body.lattice().coords(p);
            let sign = if (i + j + k) % 2 == 0 { 1.0 } else { -1.0 };
            Vec3::new(sign, sign * 0.9, sign * 0.8)
        })
        .collect();
    let mut y = vec![Vec3::ZERO; n];
    let mut rayleigh: f64 = 0.0;
    for _ in 0..200 {
        let norm = x.iter().map(|v| v.length_squared()).sum::<f64>().sqrt();
        x.iter_mut().for_each(|v| *v = *v / norm);
        apply(&x, &mut y);
        rayleigh = x.iter().zip(&y).map(|(a, b)| a.dot(*b)).sum::<f64>();
        std::mem::swap(&mut x, &mut y);
    }
    (1.02 * rayleigh.abs() / mass).min(gershgorin)
}

/// Springs above which the stiffest-mode search uses the Gershgorin bound alone (power iteration
/// would cost more than the estimate is worth).
pub const POWER_ITERATION_MAX_SPRINGS: usize = 1_000_000;

/// Spectral radius of one step of `integrator` with size `h` on `x'' = −w2·x − g·x'`: the factor
/// by which the step scales that mode's amplitude (above 1: unstable; below 1 with `g = 0`: the
/// method's own damping).
pub fn spectral_radius(integrator: Integrator, w2: f64, g: f64, h: f64) -> f64 {
    let f = |x: f64, v: f64| -w2 * x - g * v;
    let one_step = |x: f64, v: f64| -> (f64, f64) {
        match integrator {
            Integrator::Euler => (x + h * v, v + h * f(x, v)),
            Integrator::SymplecticEuler => {
                let v1 = v + h * f(x, v);
                (x + h * v1, v1)
            }
            Integrator::Rk2 => {
                let (xm, vm) = (x + 0.5 * h * v, v + 0.5 * h * f(x, v));
                (x + h * vm, v + h * f(xm, vm))
            }
            Integrator::BackwardEuler => {
                // v₁ = v + h(−w2 (x + h v₁) − g v₁), solved for v₁.
                let v1 = (v - h * w2 * x) / (1.0 + h * g + h * h * w2);
                (x + h * v1, v1)
            }
            Integrator::Sdirk2 => {
                // Two backward-Euler steps of size k = γh, the second from y + c·(Y₁ − y).
                let k = SDIRK2_GAMMA * h;
                let solve = |bx: f64, bv: f64| {
                    let v1 = (bv - k * w2 * bx) / (1.0 + k * g + k * k * w2);
                    (bx + k * v1, v1)
                };
                let (x1, v1) = solve(x, v);
                solve(x + SDIRK2_C * (x1 - x), v + SDIRK2_C * (v1 - v))
            }
            Integrator::Rk4 => {
                let (k1x, k1v) = (v, f(x, v));
                let (k2x, k2v) = (v + 0.5 * h * k1v, f(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
                let (k3x, k3v) = (v + 0.5 * h * k2v, f(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
                let (k4x, k4v) = (v + h * k3v, f(x + h * k3x, v + h * k3v));
                (
                    x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
                    v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
                )
            }
        }
    };
    let (a, c) = one_step(1.0, 0.0);
    let (b, d) = one_step(0.0, 1.0);
    let half_trace = 0.5 * (a + d);
    let det = a * d - b * c;
    let disc = half_trace * half_trace - det;
    if disc >= 0.0 {
        half_trace.abs() + disc.sqrt()
    } else {
        det.abs().sqrt()
    }
}

/// The stiffest modes of a model in some shape: what the stable time step depends on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeBounds {
    /// Squared angular frequency of the stiffest elastic mode, Ω² (1/s²).
    pub omega2: f64,
    /// Damping rate of the stiffest elastic damping mode, Γ (1/s).
    pub gamma: f64,
    /// A collision spring's stiffness over the mass (1/s²).
    pub collision_omega2: f64,
    /// A collision spring's damping over the mass (1/s).
    pub collision_gamma: f64,
}

impl ModeBounds {
    /// The bounds at the bodies' rest shapes.
    pub fn at_rest(model: &Model) -> Self {
        let rest: Vec<Vec3> = model
            .bodies()
            .iter()
            .flat_map(|b| b.lattice().rest_positions())
            .collect();
        Self::at(model, &rest)
    }

    /// The bounds with the springs as they are at positions `pos` (a deformed lattice can be
    /// stiffer than the rest shape). With several bodies, the stiffest and the most damped over
    /// the bodies (they are coupled only through contacts, which count as collision springs).
    pub fn at(model: &Model, pos: &[Vec3]) -> Self {
        let mut bounds = ModeBounds {
            omega2: 0.0,
            gamma: 0.0,
            collision_omega2: 0.0,
            collision_gamma: 0.0,
        };
        for body in model.bodies() {
            let (pos, m) = (&pos[body.points()], &body.material);
            bounds.omega2 = bounds.omega2.max(largest_eigenvalue(body, pos, true));
            bounds.gamma = bounds.gamma.max(largest_eigenvalue(body, pos, false));
            bounds.collision_omega2 = bounds.collision_omega2.max(model.k_collision / m.mass);
            bounds.collision_gamma = bounds.collision_gamma.max(model.d_collision / m.mass);
        }
        bounds
    }

    /// The largest time step (s) at which `integrator` keeps every mode from growing, by the
    /// method in the module docs; 0 when no practical step does (Euler without damping).
    pub fn stable_dt(&self, integrator: Integrator) -> f64 {
        let (kc, dc) = (self.collision_omega2, self.collision_gamma);
        // Modes sampled log-uniformly from the softest to the stiffest.
        let modes: Vec<(f64, f64)> = (0..=96)
            .map(|i| 10f64.powf(-6.0 * (1.0 - i as f64 / 96.0)))
            .flat_map(|s| {
                let (w2, g) = (s * self.omega2, s * self.gamma);
                [(w2, g), (w2 + kc, g + dc)]
            })
            .collect();
        let stable = |h: f64| {
            modes
                .iter()
                .all(|&(w2, g)| spectral_radius(integrator, w2, g, h) <= 1.0 + 1e-12)
        };
        // Scan up from a step far below the stiffest period to the first unstable one, then
        // bisect.
        let practical = 1e-3 / (self.omega2 + kc).sqrt();
        if !stable(practical) {
            return 0.0;
        }
        let (mut lo, mut hi) = (practical, practical * 1.25);
        while stable(hi) {
            lo = hi;
            hi *= 1.25;
            if hi > 1e6 {
                return f64::INFINITY;
            }
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if stable(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}

/// The largest stable time step (s) of `integrator` for `model` at its rest shape
/// ([`ModeBounds::stable_dt`]).
pub fn stable_dt(model: &Model, integrator: Integrator) -> f64 {
    ModeBounds::at_rest(model).stable_dt(integrator)
}

/// A time step to suggest after a blow-up: below both 90 % of the stability estimate at the rest
/// shape and half the current step, rounded down to two significant digits. `None` when the
/// integrator has no stable step for this model. (The state at a blow-up is already wild, so it
/// says little; a run that starts far from rest may need the advice followed more than once.)
pub fn suggest_dt(model: &Model) -> Option<f64> {
    let estimate = stable_dt(model, model.integrator);
    if estimate <= 0.0 {
        return None;
    }
    Some(round_down_2(f64::min(0.9 * estimate, 0.5 * model.dt)))
}

/// `x` rounded down to two significant digits (x > 0), as the double nearest that decimal, so
/// that it prints as one. Powers of ten up to 10²² are exact, so `m·10ᵉ` and `m/10⁻ᵉ` round once.
/// It does not allocate (a step's report makes it).
pub(crate) fn round_down_2(x: f64) -> f64 {
    let e = x.log10().floor() as i32 - 1;
    if e >= 0 {
        let scale = 10f64.powi(e);
        (x / scale).floor() * scale
    } else {
        let scale = 10f64.powi(-e);
        (x * scale).floor() / scale
    }
}

#[cfg(test)]
mod tests {
    use super::round_down_2;

    #[test]
    fn suggestions_are_rounded_down_to_two_digits_and_print_short() {
        for (x, printed) in [
            (0.5 / 60.0, "0.0083"),
            (0.000_833_333, "0.00083"),
            (0.000_25, "0.00025"),
            (0.7, "0.7"),
            (0.069_999_9, "0.069"),
            (2.71, "2.7"),
            (123.4, "120"),
            (1.0e-9 * 4.567, "0.0000000045"),
        ] {
            let r = round_down_2(x);
            assert!(r <= x, "{x} → {r}");
            assert_eq!(format!("{r}"), printed, "{x}");
        }
    }
}
