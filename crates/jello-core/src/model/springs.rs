//! The springs of a body as one source of truth: each spring's ends, kind, rest length, stiffness
//! and damping, read alike by the force kernel, the diagnostics and the stability estimate.
//!
//! By default a spring's rest length is its distance on the rest lattice and its stiffness and
//! damping are its kind's in the body's material (docs/spec.md). A body may also carry a
//! [`SpringTable`]: per spring, factors on those three values. Factors rather than values, so
//! that a material given after the table (a modulus, a change in the viewer) still applies, and
//! a factor of exactly 1 leaves a value bit for bit what it was. The kernel reads a table as one
//! contiguous run of factors per stencil entry, like the positions it runs over.

use crate::model::error::ModelError;
use crate::model::lattice::SpringKind;

/// One spring of a body, with the values the force kernel uses for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// First end: the body's own flat lattice index.
    pub a: usize,
    /// Second end: the body's own flat lattice index.
    pub b: usize,
    /// Its kind.
    pub kind: SpringKind,
    /// Rest length (m).
    pub rest: f64,
    /// Stiffness (N/m).
    pub stiffness: f64,
    /// Damping (N·s/m).
    pub damping: f64,
}

/// Factors on one spring's rest length, stiffness and damping (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringScale {
    /// Factor on the rest length (> 0): below 1 the spring pulls its ends together at rest.
    pub rest: f64,
    /// Factor on the stiffness (> 0).
    pub stiffness: f64,
    /// Factor on the damping (≥ 0).
    pub damping: f64,
}

impl SpringScale {
    /// No change.
    pub const ONE: SpringScale = SpringScale {
        rest: 1.0,
        stiffness: 1.0,
        damping: 1.0,
    };

    /// Fails on a factor that is not finite, a rest or stiffness factor that is not positive, or
    /// a negative damping factor.
    pub fn check(&self) -> Result<(), ModelError> {
        crate::model::error::positive("rest length factor", self.rest)?;
        crate::model::error::positive("stiffness factor", self.stiffness)?;
        crate::model::error::non_negative("damping factor", self.damping)
    }

    /// This scale followed by `other`: the factors multiplied.
    pub fn then(self, other: SpringScale) -> SpringScale {
        SpringScale {
            rest: self.rest * other.rest,
            stiffness: self.stiffness * other.stiffness,
            damping: self.damping * other.damping,
        }
    }
}

/// Per spring of a body, its [`SpringScale`]: for each of the three values either `16 × points`
/// factors, at index `entry · points + a` for the spring of stencil entry `entry` from point `a`
/// (entries without a spring hold 1), or none when every factor of that value is 1 (a body that
/// only has its own rest lengths stores and streams only those). Entry-major, so that the springs
/// of one entry over a run of first ends read one contiguous run of factors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpringTable {
    rest: Option<Vec<f64>>,
    stiffness: Option<Vec<f64>>,
    damping: Option<Vec<f64>>,
}

/// Factors of 1 for a value without factors of its own: one run's worth, small enough to stay in
/// the L1 cache.
static ONES: [f64; MAX_RUN] = [1.0; MAX_RUN];

/// The longest run of springs [`SpringTable::run`] hands out.
pub(crate) const MAX_RUN: usize = 512;

impl SpringTable {
    /// A table of all ones for a body of `points` lattice points.
    pub(crate) fn ones(points: usize) -> Self {
        SpringTable {
            rest: Some(vec![1.0; 16 * points]),
            stiffness: Some(vec![1.0; 16 * points]),
            damping: Some(vec![1.0; 16 * points]),
        }
    }

    fn values(&self) -> [&Option<Vec<f64>>; 3] {
        [&self.rest, &self.stiffness, &self.damping]
    }

    /// The factors of the spring of stencil entry `entry` from point `a` of a body of `points`.
    pub(crate) fn get(&self, points: usize, entry: usize, a: usize) -> SpringScale {
        let i = entry * points + a;
        let [rest, stiffness, damping] = self.values().map(|v| v.as_ref().map_or(1.0, |v| v[i]));
        SpringScale {
            rest,
            stiffness,
            damping,
        }
    }

    /// Sets the factors of one spring (of a table made by [`SpringTable::ones`]).
    pub(crate) fn set(&mut self, points: usize, entry: usize, a: usize, scale: SpringScale) {
        let i = entry * points + a;
        for (v, f) in [&mut self.rest, &mut self.stiffness, &mut self.damping]
            .into_iter()
            .zip([scale.rest, scale.stiffness, scale.damping])
        {
            v.as_mut().expect("a full table")[i] = f;
        }
    }

    /// The table without the values whose factors are all exactly 1; `None` when that is all of
    /// them (the table changes nothing).
    pub(crate) fn trimmed(mut self) -> Option<Self> {
        for v in [&mut self.rest, &mut self.stiffness, &mut self.damping] {
            if v.as_ref().is_some_and(|v| v.iter().all(|&f| f == 1.0)) {
                *v = None;
            }
        }
        (self.values().iter().any(|v| v.is_some())).then_some(self)
    }

    /// A table with every value's factors stored (those without hold ones), to be changed.
    pub(crate) fn filled(mut self, points: usize) -> Self {
        for v in [&mut self.rest, &mut self.stiffness, &mut self.damping] {
            v.get_or_insert_with(|| vec![1.0; 16 * points]);
        }
        self
    }

    /// The factors of stencil entry `entry` for the first ends `from .. from + len` of a body of
    /// `points` (`len` at most [`MAX_RUN`]): rest, stiffness, damping.
    #[inline]
    pub(crate) fn run(&self, points: usize, entry: usize, from: usize, len: usize) -> [&[f64]; 3] {
        let at = entry * points + from;
        self.values()
            .map(|v| v.as_ref().map_or(&ONES[..len], |v| &v[at..at + len]))
    }
}

/// Springs as flat arrays, one entry per spring (all of the same length).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Springs {
    /// First point of each spring (flat index).
    pub a: Vec<u32>,
    /// Second point of each spring (flat index).
    pub b: Vec<u32>,
    /// Rest length of each spring (m).
    pub rest_len: Vec<f64>,
    /// Kind of each spring.
    pub kind: Vec<SpringKind>,
    /// Stiffness of each spring (N/m).
    pub stiffness: Vec<f64>,
    /// Damping of each spring (N·s/m).
    pub damping: Vec<f64>,
}

impl Springs {
    /// Appends `spring`, its ends shifted by `first`.
    pub(crate) fn push(&mut self, spring: &Spring, first: usize) {
        self.a.push((first + spring.a) as u32);
        self.b.push((first + spring.b) as u32);
        self.rest_len.push(spring.rest);
        self.kind.push(spring.kind);
        self.stiffness.push(spring.stiffness);
        self.damping.push(spring.damping);
    }

    /// Number of springs.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// True when there are no springs.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Number of springs of each kind, indexed by `SpringKind as usize`.
    pub fn count_by_kind(&self) -> [usize; 3] {
        let mut counts = [0; 3];
        for &k in &self.kind {
            counts[k as usize] += 1;
        }
        counts
    }
}
