//! Instruction-set tiers: every hot loop compiled once per tier, the tier picked at run time.
//!
//! On x86-64 the tiers are AVX-512 (F, DQ, VL), AVX2 + FMA (x86-64-v3) and the baseline (SSE2);
//! on aarch64 the baseline is NEON; in wasm it is SIMD128 when the build enables it. The best
//! tier the CPU has is used unless the environment variable `JELLO_SIMD` names another
//! (`baseline`, `avx2` or `avx512`), so every tier can be tested and timed on one machine.
//!
//! The functions compiled per tier do element-wise IEEE arithmetic only. Rust never reassociates
//! or contracts `a * b + c` into a fused multiply-add on its own, so enabling FMA changes no
//! result: every tier computes the same bits (a test checks saved states across tiers); wider
//! tiers just do it more lanes at a time.
//!
//! Why a macro of our own rather than the `multiversion` or `pulp` crates: the tier must be
//! forceable per process (`JELLO_SIMD`, and [`force_tier`] in tests and benchmarks), and
//! `multiversion`'s dispatchers always pick the best tier the CPU has; the macro is a few lines
//! and generates the same code.

use std::fmt;
use std::sync::atomic::{AtomicU8, Ordering};

/// An instruction-set tier the hot loops are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Tier {
    /// The target's baseline: SSE2 on x86-64, NEON on aarch64, SIMD128 in wasm built with it.
    Baseline = 1,
    /// x86-64 with AVX2 and FMA.
    Avx2 = 2,
    /// x86-64 with AVX-512 F, DQ and VL (and AVX2, FMA).
    Avx512 = 3,
}

impl Tier {
    /// Every tier, slowest first.
    pub const ALL: [Tier; 3] = [Tier::Baseline, Tier::Avx2, Tier::Avx512];

    /// The name `JELLO_SIMD` takes.
    pub fn name(self) -> &'static str {
        match self {
            Tier::Baseline => "baseline",
            Tier::Avx2 => "avx2",
            Tier::Avx512 => "avx512",
        }
    }

    /// What the tier is on this build's target, for reports: `avx512`, `avx2`, or the
    /// baseline's own name (`sse2`, `neon`, `simd128`, `scalar`).
    pub fn describe(self) -> &'static str {
        match self {
            Tier::Baseline => baseline_name(),
            t => t.name(),
        }
    }

    /// The tier named `name` (any case).
    pub fn parse(name: &str) -> Option<Tier> {
        Tier::ALL
            .into_iter()
            .find(|t| t.name().eq_ignore_ascii_case(name.trim()))
    }

    /// True when this CPU can run the tier.
    pub fn is_supported(self) -> bool {
        match self {
            Tier::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Tier::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            Tier::Avx512 => {
                Tier::Avx2.is_supported()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The fastest tier this CPU supports.
    pub fn best() -> Tier {
        Tier::ALL
            .into_iter()
            .rev()
            .find(|t| t.is_supported())
            .unwrap_or(Tier::Baseline)
    }
}

impl fmt::Display for Tier {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

/// The name of the target's baseline tier.
fn baseline_name() -> &'static str {
    if cfg!(target_arch = "x86_64") {
        "sse2"
    } else if cfg!(target_arch = "aarch64") {
        "neon"
    } else if cfg!(all(target_arch = "wasm32", target_feature = "simd128")) {
        "simd128"
    } else {
        "scalar"
    }
}

/// A `JELLO_SIMD` value that names no tier, or a tier this CPU cannot run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TierError(pub String);

impl fmt::Display for TierError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for TierError {}

/// The tier `JELLO_SIMD` asks for, or the best one when it is unset or empty.
///
/// Fails when the value names no tier or one this CPU cannot run. Front ends call this at start
/// to report such a value; the core itself then runs the best tier (it never executes
/// instructions the CPU lacks).
pub fn tier_from_env() -> Result<Tier, TierError> {
    let value = match std::env::var("JELLO_SIMD") {
        Ok(v) if !v.trim().is_empty() => v,
        _ => return Ok(Tier::best()),
    };
    let supported: Vec<&str> = Tier::ALL
        .into_iter()
        .filter(|t| t.is_supported())
        .map(Tier::name)
        .collect();
    let tier = Tier::parse(&value).ok_or_else(|| {
        TierError(format!(
            "JELLO_SIMD={value:?} names no tier: expected baseline, avx2 or avx512 \
             (this CPU can run {})",
            supported.join(", ")
        ))
    })?;
    if !tier.is_supported() {
        return Err(TierError(format!(
            "JELLO_SIMD={value:?}: this CPU cannot run the {} tier (it can run {})",
            tier.name(),
            supported.join(", ")
        )));
    }
    Ok(tier)
}

/// The tier in use: 0 until first asked for, then a [`Tier`] as `u8`.
static ACTIVE: AtomicU8 = AtomicU8::new(0);

/// The tier the hot loops run: the one [`force_tier`] set, else `JELLO_SIMD`'s when valid, else
/// the best this CPU has.
#[inline]
pub fn active_tier() -> Tier {
    match ACTIVE.load(Ordering::Relaxed) {
        1 => Tier::Baseline,
        2 => Tier::Avx2,
        3 => Tier::Avx512,
        _ => {
            let tier = tier_from_env().unwrap_or_else(|_| Tier::best());
            // Unless `force_tier` got there first.
            match ACTIVE.compare_exchange(0, tier as u8, Ordering::Relaxed, Ordering::Relaxed) {
                Ok(_) => tier,
                Err(_) => active_tier(),
            }
        }
    }
}

/// Runs the hot loops of this process on `tier` from now on (every thread). Results do not
/// change, only speed. Fails, changing nothing, when the CPU cannot run it.
pub fn force_tier(tier: Tier) -> Result<(), TierError> {
    if !tier.is_supported() {
        return Err(TierError(format!(
            "this CPU cannot run the {} tier",
            tier.name()
        )));
    }
    ACTIVE.store(tier as u8, Ordering::Relaxed);
    Ok(())
}

/// Defines `fn $name(args) { body }` compiled once per tier of the target, and calls the one
/// [`active_tier`] names. Use it for loops that should vectorise, including bodies called from
/// other threads (a closure handed to rayon does not inherit its caller's target features).
macro_rules! multiversion {
    ($(#[$attr:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            fn body($($arg: $ty),*) $(-> $ret)? $body

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx512($($arg: $ty),*) $(-> $ret)? {
                body($($arg),*)
            }

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                body($($arg),*)
            }

            #[cfg(target_arch = "x86_64")]
            match $crate::compute::simd::active_tier() {
                // SAFETY: `active_tier` names only tiers whose features the CPU has.
                $crate::compute::simd::Tier::Avx512 => return unsafe { avx512($($arg),*) },
                // SAFETY: as above.
                $crate::compute::simd::Tier::Avx2 => return unsafe { avx2($($arg),*) },
                $crate::compute::simd::Tier::Baseline => {}
            }
            body($($arg),*)
        }
    };
}

pub(crate) use multiversion;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for t in Tier::ALL {
            assert_eq!(Tier::parse(t.name()), Some(t));
            assert_eq!(Tier::parse(&t.name().to_uppercase()), Some(t));
        }
        assert_eq!(Tier::parse("sse4"), None);
    }
}
