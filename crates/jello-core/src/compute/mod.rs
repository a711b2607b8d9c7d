//! The machinery the hot loops run on, with no physics in it: the instruction-set tiers every
//! kernel is compiled for ([`simd`]), the structure-of-arrays layout the kernels read and write
//! ([`soa`], with `split.rs` to hand each chunk its part of several buffers), and the team of
//! threads that shares a step's loops (`team.rs`). Results never depend on the tier or the
//! number of threads: each is checked bit for bit.

pub mod simd;
pub mod soa;
pub(crate) mod split;
pub(crate) mod team;
