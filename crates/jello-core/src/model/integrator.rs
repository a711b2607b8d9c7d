//! The integrators' names and their aliases: the four explicit ones of the classic world files
//! (docs/spec.md), and Jello's two implicit ones.

use std::fmt;
use std::str::FromStr;

/// A time-stepping scheme. The explicit ones keep exactly the meanings docs/spec.md gives their
/// names; `BackwardEuler` and `SDIRK2` are Jello's own (docs/implicit.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Integrator {
    /// Explicit (forward) Euler: `a = a(p, v); p += dt·v` (old velocity); `v += dt·a`.
    Euler,
    /// Explicit midpoint: `y += dt·f(y + dt/2·f(y))`. Files in the wild also say `Midpoint`, `MP`.
    Rk2,
    /// Classical fourth-order Runge–Kutta.
    Rk4,
    /// Symplectic (semi-implicit) Euler: `v += dt·a(p, v)`, then `p += dt·v` (new velocity).
    SymplecticEuler,
    /// Backward (implicit) Euler: `v₁ = v₀ + dt·a(p₀ + dt·v₁, v₁)`, `p₁ = p₀ + dt·v₁`, solved by
    /// Newton's method (see [`crate::integrate::implicit`]); stable at any time step. Also `Implicit`.
    BackwardEuler,
    /// SDIRK2, the two-stage L-stable singly diagonally implicit Runge–Kutta method of
    /// Alexander (1977), `γ = 1 − √2/2`: two backward-Euler steps of size `γ·dt`, the second from
    /// an extrapolation of the first (see [`crate::integrate::implicit`]). Second order and stable at any
    /// time step; it damps far less than backward Euler at the frequencies a step resolves and,
    /// unlike the implicit midpoint or trapezoidal rule, still damps the ones it does not.
    Sdirk2,
}

impl Integrator {
    /// Every integrator, in the order they are listed to users.
    pub const ALL: [Integrator; 6] = [
        Integrator::Euler,
        Integrator::Rk2,
        Integrator::Rk4,
        Integrator::SymplecticEuler,
        Integrator::BackwardEuler,
        Integrator::Sdirk2,
    ];

    /// The explicit integrators (a fixed number of force evaluations per step), which docs/spec.md
    /// names.
    pub const EXPLICIT: [Integrator; 4] = [
        Integrator::Euler,
        Integrator::Rk2,
        Integrator::Rk4,
        Integrator::SymplecticEuler,
    ];

    /// True for an integrator that solves an implicit equation each step (no stability limit).
    pub fn is_implicit(self) -> bool {
        matches!(self, Integrator::BackwardEuler | Integrator::Sdirk2)
    }

    /// Canonical name, as written to world files.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Euler => "Euler",
            Integrator::Rk2 => "RK2",
            Integrator::Rk4 => "RK4",
            Integrator::SymplecticEuler => "SymplecticEuler",
            Integrator::BackwardEuler => "BackwardEuler",
            Integrator::Sdirk2 => "SDIRK2",
        }
    }

    /// Other accepted spellings (all matched without regard to case).
    pub fn aliases(self) -> &'static [&'static str] {
        match self {
            Integrator::Euler => &[],
            Integrator::Rk2 => &["Midpoint", "MP"],
            Integrator::Rk4 => &[],
            Integrator::SymplecticEuler => &["Symplectic", "SemiImplicitEuler"],
            Integrator::BackwardEuler => &["Implicit", "ImplicitEuler"],
            Integrator::Sdirk2 => &["SDIRK"],
        }
    }

    /// Looks a name up, ignoring case; `None` when it is not a known name or alias.
    pub fn from_name(name: &str) -> Option<Integrator> {
        Integrator::ALL.into_iter().find(|i| {
            i.name().eq_ignore_ascii_case(name)
                || i.aliases().iter().any(|a| a.eq_ignore_ascii_case(name))
        })
    }

    /// Order of accuracy (global error ∝ dtᵒʳᵈᵉʳ).
    pub fn order(self) -> u32 {
        match self {
            Integrator::Euler | Integrator::SymplecticEuler | Integrator::BackwardEuler => 1,
            Integrator::Rk2 | Integrator::Sdirk2 => 2,
            Integrator::Rk4 => 4,
        }
    }

    /// Force evaluations per step; `None` for an implicit integrator (as many as its solver
    /// takes).
    pub fn force_evaluations(self) -> Option<usize> {
        match self {
            Integrator::Euler | Integrator::SymplecticEuler => Some(1),
            Integrator::Rk2 => Some(2),
            Integrator::Rk4 => Some(4),
            Integrator::BackwardEuler | Integrator::Sdirk2 => None,
        }
    }

    /// The known names with their aliases, for error messages and help text:
    /// `Euler, RK2 (also Midpoint, MP), RK4, SymplecticEuler (also Symplectic, SemiImplicitEuler)`.
    pub fn known_names() -> String {
        Integrator::ALL
            .iter()
            .map(|i| {
                if i.aliases().is_empty() {
                    i.name().to_string()
                } else {
                    format!("{} (also {})", i.name(), i.aliases().join(", "))
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl fmt::Display for Integrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The error for a name that is not a known integrator.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownIntegrator(pub String);

impl fmt::Display for UnknownIntegrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown integrator \"{}\"; known integrators: {}",
            self.0,
            Integrator::known_names()
        )
    }
}

impl std::error::Error for UnknownIntegrator {}

impl FromStr for Integrator {
    type Err = UnknownIntegrator;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Integrator::from_name(s).ok_or_else(|| UnknownIntegrator(s.to_string()))
    }
}
