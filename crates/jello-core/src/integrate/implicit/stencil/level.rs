//! A coarse level of the multigrid in stencil order.
//!
//! The aggregates of a body's lattice (2×2×2 points, coordinates halved) form a lattice too, its
//! counts halved and rounded up, numbered in its own flat order; and two aggregates that a spring
//! joins differ by at most one in each coordinate (the longest springs span two points). So each
//! pair of a coarse level has a slot `e·n + a` for one of the 13 entries `e` of the 27-point
//! half stencil ([`COARSE_STENCIL`]), `a` its first node, and the level's `A·x` is the fine
//! level's product: loops over contiguous runs of slots, vectorised and split over the team's
//! threads, each row summed in the same order whoever computes it. A loop over the level's list
//! of pairs, which gathers and scatters by index, cost as much as the fine product itself with a
//! ninth of its pairs (32³ cube resting on a floor, 2 threads).

use super::{product, Input, Precision, Ranges, Span};
use crate::compute::team;
use crate::integrate::implicit::sym::Sym;
use crate::vec3::Vec3;

/// The offsets `(di, dj, dk)` of the 27-point half stencil: every offset in `{−1, 0, 1}³` whose
/// first non-zero component is positive.
pub(in crate::integrate::implicit) const COARSE_STENCIL: [[isize; 3]; 13] = [
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 1, 0],
    [1, -1, 0],
    [1, 0, 1],
    [1, 0, -1],
    [0, 1, 1],
    [0, 1, -1],
    [1, 1, 1],
    [1, 1, -1],
    [1, -1, 1],
    [1, -1, -1],
];

/// [`LevelStencil::pair_at`] of a slot without a pair.
const NO_PAIR: u32 = u32::MAX;

/// Fewest slots in a chunk of [`LevelStencil::set`] spread over threads.
const MIN_SLOTS: usize = 4096;

/// One coarse level's pair blocks by stencil slot, with the buffers of its product.
#[derive(Clone, Debug, Default)]
pub(in crate::integrate::implicit) struct LevelStencil {
    n: usize,
    spans: Vec<Span>,
    /// Each lattice's point counts, as its span's.
    counts: Vec<[usize; 3]>,
    blocks: [Vec<f64>; 6],
    blocks_single: [Vec<f32>; 6],
    /// Each slot's pair (its index in the level's list of pairs), or [`NO_PAIR`].
    pair_at: Vec<u32>,
    x: [Vec<f64>; 3],
    x_single: [Vec<f32>; 3],
    ranges: Ranges,
}

impl LevelStencil {
    /// For a level whose nodes are the lattices `lattices` (each its first node and its point
    /// counts), one after another, every block zero.
    pub fn new(lattices: &[(usize, [usize; 3])]) -> LevelStencil {
        let n = lattices.iter().map(|&(_, [a, b, c])| a * b * c).sum();
        let spans = (lattices.iter())
            .map(|&(first, [nx, ny, nz])| {
                let mut offset = [0; 16];
                for (o, d) in offset.iter_mut().zip(COARSE_STENCIL) {
                    let flat = (d[0] * ny as isize + d[1]) * nz as isize + d[2];
                    *o = flat.max(0) as usize;
                }
                Span {
                    first,
                    len: nx * ny * nz,
                    offset,
                }
            })
            .collect();
        let slots = COARSE_STENCIL.len() * n;
        LevelStencil {
            n,
            spans,
            counts: lattices.iter().map(|&(_, c)| c).collect(),
            blocks: std::array::from_fn(|_| vec![0.0; slots]),
            blocks_single: std::array::from_fn(|_| vec![0.0; slots]),
            pair_at: vec![NO_PAIR; slots],
            x: std::array::from_fn(|_| vec![0.0; n]),
            x_single: std::array::from_fn(|_| vec![0.0; n]),
            ranges: Ranges::default(),
        }
    }

    /// How many lattices the level holds.
    pub fn lattice_count(&self) -> usize {
        self.spans.len()
    }

    /// The slot of the pair of nodes `a` and `c` (flat indices of this level), or `None` when
    /// they are not in one lattice or not neighbours.
    pub fn slot(&self, a: usize, c: usize) -> Option<u32> {
        let (a, c) = (a.min(c), a.max(c));
        let (span, counts) = self
            .spans
            .iter()
            .zip(&self.counts)
            .find(|(s, _)| (s.first..s.first + s.len).contains(&a))?;
        if c >= span.first + span.len {
            return None;
        }
        let coords = |p: usize| {
            let [_, ny, nz] = *counts;
            let q = p - span.first;
            [q / (ny * nz), q / nz % ny, q % nz].map(|v| v as isize)
        };
        let (ca, cc) = (coords(a), coords(c));
        let d = [cc[0] - ca[0], cc[1] - ca[1], cc[2] - ca[2]];
        let e = COARSE_STENCIL.iter().position(|&o| o == d)?;
        Some((e * self.n + a) as u32)
    }

    /// The level's pairs: pair `k` at slot `slots[k]` (see [`slot`](Self::slot)), no pair
    /// elsewhere.
    pub fn place_pairs(&mut self, slots: &[u32]) {
        self.pair_at.fill(NO_PAIR);
        for (k, &slot) in slots.iter().enumerate() {
            self.pair_at[slot as usize] = k as u32;
        }
    }

    /// Every slot's block: `blocks[k]` at pair `k`'s slot ([`place_pairs`](Self::place_pairs)),
    /// zero elsewhere. Slot by slot over the team (on the leader alone, scattering the pairs'
    /// blocks was 0.7 ms of each assembly of a 32³ cube on two threads, while the other waited).
    pub fn set(&mut self, blocks: &[Sym]) {
        let pair_at = &self.pair_at[..];
        let size = team::chunk_size(pair_at.len(), MIN_SLOTS);
        let parts = (
            self.blocks.each_mut().map(|b| &mut b[..]),
            self.blocks_single.each_mut().map(|b| &mut b[..]),
        );
        team::for_each_chunk_pair(parts, size, &|chunk, (mut double, mut single)| {
            let at = chunk * size;
            for (i, &k) in pair_at[at..at + double[0].len()].iter().enumerate() {
                let block = blocks.get(k as usize).unwrap_or(&[0.0; 6]);
                for ((double, single), &v) in double.iter_mut().zip(&mut single).zip(block) {
                    (double[i], single[i]) = (v, v as f32);
                }
            }
        });
    }

    /// `t = r − (own·e + blocks·e)`, the blocks' part in `precision`.
    pub fn residual(
        &mut self,
        own: &[Sym],
        r: &[Vec3],
        e: &[Vec3],
        t: &mut [Vec3],
        precision: Precision,
    ) {
        let blocks = (&self.blocks, &self.blocks_single);
        let buffers = (&mut self.x, &mut self.x_single);
        let (spans, n) = (&self.spans[..], self.n);
        let out = |p: usize, row: Vec3| r[p] - row;
        product(
            &mut self.ranges,
            (spans, n),
            blocks,
            buffers,
            (own, None),
            (e, Input::Load),
            precision,
            t,
            &out,
            None,
        );
    }
}
