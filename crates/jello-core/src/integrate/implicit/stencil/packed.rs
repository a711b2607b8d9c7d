//! The springs' single-precision blocks again in 16 bits, for the products of the
//! single-precision solvers on large lattices: each stencil entry's blocks of a tile of
//! [`TILE`] first ends, all six components, in whole steps of the tile's largest magnitude over
//! `i16::MAX` ([`pack_tile`]), and each tile's step. A product's spring loop streams its blocks
//! from memory (12.6 MB in single precision at 32³): on one thread of a 2-vCPU AMD EPYC with
//! AVX2 a product took 1.36–1.65 ms, and 0.84 ms with its blocks held in the cache; with
//! these, half the bytes, 0.97–1.16 ms (2026-12-07).
//!
//! The rounding is at most half a step, `2⁻¹⁶` of the tile's largest component: a tile's blocks
//! are its springs' (one entry: one rest length and stiffness in a lattice) and alike, so each
//! keeps 4–5 significant digits, near the single-precision solves' least reduction
//! (`SINGLE_PRECISION_REDUCTION`, 1e-4), where they stop: the conjugate gradients steer by it,
//! and the residual that decides convergence stays in double precision (the 32³ cube dropped on
//! a floor took 10.25 → 10.52 conjugate-gradient iterations a step, as many Newton iterations).
//! Not where a field swirls
//! ([`SpringMatrix::pack_products`](super::SpringMatrix::pack_products)), nor below
//! [`PACKED_FROM`](super::PACKED_FROM) points, where the blocks stay in the caches. The blocks
//! are packed at the first such product after an assembly; the diagonal and the multigrid read
//! the single-precision blocks, exact solves the double-precision ones.

use super::kernels::{pack_tile, spring_forces_packed};
use super::TILE;
use crate::compute::team;

/// The 16-bit blocks of a [`SpringMatrix`](super::SpringMatrix) and each tile's step.
#[derive(Clone, Debug, Default)]
pub(super) struct Packed {
    /// `[xx, yy, zz, xy, xz, yz]`, each entry's run `tiles·TILE` long (the points rounded up
    /// to whole tiles, so that every entry's tiles start at a multiple of [`TILE`]: tile `t` of
    /// entry `e` is the run `(e·tiles + t)·TILE ..` of [`TILE`]).
    values: [Vec<i16>; 6],
    /// Each tile's step, at `e·tiles + t`.
    steps: Vec<f32>,
    /// Tiles per entry.
    tiles: usize,
}

impl Packed {
    /// Sized for `n` points' 16 entries, every block zero.
    pub(super) fn new(n: usize) -> Self {
        let tiles = n.div_ceil(TILE);
        Packed {
            values: std::array::from_fn(|_| vec![0; 16 * tiles * TILE]),
            steps: vec![0.0; 16 * tiles],
            tiles,
        }
    }

    /// Packs the single-precision blocks `blocks` (by slot `e·n + p`), a tile at a time over
    /// the team (each tile's values and step depend on its blocks alone: the same on any
    /// number of threads).
    pub(super) fn pack(&mut self, blocks: &[Vec<f32>; 6], n: usize) {
        let tiles = self.tiles;
        let [a, b, c, d, e, f] = &mut self.values;
        let values = [a, b, c, d, e, f].map(|v| &mut v[..]);
        team::for_each_chunk_into(values, TILE, &mut self.steps, &|unit, packed| {
            let (entry, tile) = (unit / tiles, unit % tiles);
            let first = entry * n + tile * TILE;
            let len = TILE.min(n - tile * TILE);
            let runs = std::array::from_fn(|c| &blocks[c][first..first + len]);
            pack_tile(runs, packed)
        });
    }

    /// The `entry_forces` of [`rows`](super::kernels::rows) from the 16-bit blocks of a
    /// matrix over `n` points: slot `at = e·n + q` (the run from `q`, within one tile) at
    /// `e·stride + q` here, in its tile's steps.
    #[allow(clippy::type_complexity)]
    pub(super) fn entry_forces(
        &self,
        n: usize,
    ) -> impl Fn(usize, usize, usize, [&mut [f32]; 3], [&[f32]; 3], [&[f32]; 3]) + Sync + '_ {
        let stride = self.tiles * TILE;
        move |at, q, _, f, x, xn| {
            let (entry, len) = ((at - q) / n, f[0].len());
            let first = entry * stride + q;
            let blocks = std::array::from_fn(|c| &self.values[c][first..first + len]);
            let step = self.steps[entry * self.tiles + q / TILE];
            spring_forces_packed(f, x, xn, blocks, step);
        }
    }
}
