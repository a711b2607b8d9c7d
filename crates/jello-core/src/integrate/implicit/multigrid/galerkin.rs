//! The first coarse level's operator over each large full lattice, summed from the fine blocks
//! in stencil order.
//!
//! The Galerkin product of the aggregation (see the parent module) adds every spring between two
//! aggregates into their coarse pair. Over a full lattice whose aggregates are numbered in the
//! order of their halved coordinates, which aggregates a spring joins follows from its stencil
//! entry `e` and its first end's parity `r ∈ {0, 1}³` alone: the aggregate of its first end
//! `p = 2J + r` is `J`, that of its second end `p + dₑ` is `J + D`, `D = ⌊(r + dₑ)/2⌋`. So for each
//! of the 16 × 8 pairs `(e, r)` the springs of one coarse stencil entry are a strided run of
//! slots, summed plane by plane of aggregates into the coarse blocks of that plane, in the order
//! of `(e, r)` whoever computes the plane (the same bits on any number of threads), each fine
//! block read once and in order. The list of fine pairs each coarse pair sums, which serves every
//! other lattice and the coarser levels, gathers the blocks by index instead: over a 32³ cube on
//! one thread (Intel Xeon with AVX-512) 3.3 ms an assembly, here 1.3 ms (the first level's whole
//! restriction 4.4 → 2.9 ms).

use super::{aggregates_in_order, Level, Restriction, MIN_NODES, STENCIL_NODES};
use crate::compute::team;
use crate::integrate::implicit::stencil::COARSE_STENCIL;
use crate::integrate::implicit::sym::Sym;
use crate::model::lattice::STENCIL;
use crate::model::Model;

/// A full lattice whose first coarse level is summed here.
#[derive(Clone, Debug)]
pub(super) struct Part {
    /// Its first fine point and its counts.
    fine: usize,
    counts: [usize; 3],
    /// Its first aggregate and the aggregates' counts (halved, rounded up).
    coarse: usize,
    halves: [usize; 3],
    /// Where its sums start in [`Galerkin::sums`]: plane by plane of aggregates, each plane's
    /// coarse stencil entries one after another, each entry's aggregates in order.
    at: usize,
}

/// The coarse pairs of the first level over the large full lattices, summed in stencil order;
/// the others by the list of fine pairs.
#[derive(Clone, Debug, Default)]
pub(super) struct Galerkin {
    pub(super) parts: Vec<Part>,
    /// Each part's coarse blocks, by component (see [`Part::at`]).
    sums: [Vec<f64>; 6],
    /// Each coarse pair's place in `sums`, or [`GATHERED`] for a pair of another lattice
    /// (summed from the list of fine pairs).
    pub(super) places: Vec<u32>,
}

/// The place of a coarse pair outside the parts (see [`Galerkin::places`]).
pub(super) const GATHERED: u32 = u32::MAX;

impl Galerkin {
    /// For `model`'s lattices, `down` the aggregation of its points and `pairs` the first coarse
    /// level's pairs: each full lattice whose aggregates are in the order of their halved
    /// coordinates and number [`STENCIL_NODES`] or more.
    pub(super) fn new(model: &Model, down: &Restriction, pairs: &[[u32; 2]]) -> Galerkin {
        let mut parts: Vec<Part> = Vec::new();
        let mut at = 0;
        for body in model.bodies() {
            let points = body.points();
            let counts = body.lattice().counts;
            let halves = counts.map(|n| n.div_ceil(2));
            let coarse = points.clone().next().map_or(0, |p| down.parent[p] as usize);
            let in_order = aggregates_in_order(body, down);
            let nodes: usize = halves.iter().product();
            if body.is_full() && in_order && nodes >= STENCIL_NODES {
                parts.push(Part {
                    fine: points.start,
                    counts,
                    coarse,
                    halves,
                    at,
                });
                at += COARSE_STENCIL.len() * nodes;
            }
        }
        assert!(at < GATHERED as usize, "{at} coarse blocks");
        let places = (pairs.iter())
            .map(|&[a, c]| {
                Galerkin::place(&parts, a as usize, c as usize).map_or(GATHERED, |at| at as u32)
            })
            .collect();
        Galerkin {
            parts,
            sums: std::array::from_fn(|_| vec![0.0; at]),
            places,
        }
    }

    /// Where the coarse pair of aggregates `a < c` lies in the sums, if in a part.
    fn place(parts: &[Part], a: usize, c: usize) -> Option<usize> {
        let part = parts
            .iter()
            .find(|p| (p.coarse..p.coarse + p.halves.iter().product::<usize>()).contains(&a))?;
        let [_, cy, cz] = part.halves;
        let coords = |q: usize| {
            let q = q - part.coarse;
            [q / (cy * cz), q / cz % cy, q % cz].map(|v| v as isize)
        };
        let (ca, cc) = (coords(a), coords(c));
        let d = [cc[0] - ca[0], cc[1] - ca[1], cc[2] - ca[2]];
        let e = COARSE_STENCIL.iter().position(|&o| o == d)?;
        let [i, j, k] = ca.map(|v| v as usize);
        Some(part.at + ((i * COARSE_STENCIL.len() + e) * cy + j) * cz + k)
    }

    /// Whether some lattice's coarse pairs are summed here.
    pub(super) fn is_used(&self) -> bool {
        !self.parts.is_empty()
    }

    /// The first coarse level's pair blocks into `coarse.blocks`: the parts' from the fine
    /// blocks in stencil order (`components`, slot `e·n + p`), the others' summed by `gather`
    /// from the list of fine pairs.
    pub(super) fn restrict(
        &mut self,
        components: &[Vec<f32>; 6],
        coarse: &mut Level,
        gather: &(dyn Fn(usize) -> Sym + Sync),
    ) {
        let n = components[0].len() / STENCIL.len();
        for part in &self.parts {
            let [cx, cy, cz] = part.halves;
            let plane = COARSE_STENCIL.len() * cy * cz;
            let sums = self
                .sums
                .each_mut()
                .map(|s| &mut s[part.at..part.at + cx * plane]);
            let size = team::chunk_size(cx, MIN_NODES.div_ceil(cy * cz)) * plane;
            team::for_each_chunk(sums, size, &|chunk, mut sums| {
                let first = chunk * size / plane;
                for (i, start) in (0..sums[0].len()).step_by(plane).enumerate() {
                    let out = sums.each_mut().map(|s| &mut s[start..start + plane]);
                    sum_plane(part, components, n, first + i, out);
                }
            });
        }
        // Each coarse pair from its place in the sums, or gathered: over the team (on the
        // leader alone, the copy from the sums was 0.46 ms of each assembly of a 32³ cube on
        // two threads, while the other thread waited).
        let (sums, places) = (&self.sums, &self.places[..]);
        let size = team::chunk_size(places.len(), MIN_NODES);
        team::for_each_chunk([&mut coarse.blocks[..]], size, &|chunk, [blocks]| {
            for (k, (b, &at)) in
                (chunk * size..).zip(blocks.iter_mut().zip(&places[chunk * size..]))
            {
                *b = match at {
                    GATHERED => gather(k),
                    at => std::array::from_fn(|c| sums[c][at as usize]),
                };
            }
        });
    }
}

crate::compute::simd::multiversion! {
    /// The coarse blocks of the aggregates of plane `i` of `part` into `out` (by component:
    /// each coarse stencil entry's aggregates of the plane in order), summed over the fine
    /// stencil entries and parities in order.
    fn sum_plane(part: &Part, blocks: &[Vec<f32>; 6], n: usize, i: usize, out: [&mut [f64]; 6]) {
        sum_plane_each(part, blocks, n, i, out)
    }
}

/// [`sum_plane`]'s loops (inlined into each tier's copy).
#[inline(always)]
fn sum_plane_each(
    part: &Part,
    blocks: &[Vec<f32>; 6],
    n: usize,
    i: usize,
    mut out: [&mut [f64]; 6],
) {
    for o in out.iter_mut() {
        o.fill(0.0);
    }
    let [nx, ny, nz] = part.counts.map(|c| c as isize);
    let [cx, cy, cz] = part.halves.map(|c| c as isize);
    for (e, &(d, _)) in STENCIL.iter().enumerate() {
        for parity in 0..8 {
            let r = [parity >> 2 & 1, parity >> 1 & 1, parity & 1];
            // The partner's aggregate, relative to the first end's.
            let to: [isize; 3] = std::array::from_fn(|a| (r[a] + d[a]).div_euclid(2));
            if to == [0; 3] {
                continue;
            }
            // The coarse pair's entry, and its first aggregate relative to the spring's first
            // end's: that one itself, or the partner's where `to` points backwards.
            let (entry, back) = match COARSE_STENCIL.iter().position(|&o| o == to) {
                Some(entry) => (entry, [0; 3]),
                None => {
                    let from = to.map(|t| -t);
                    let entry = COARSE_STENCIL.iter().position(|&o| o == from);
                    (entry.expect("a neighbour's offset"), to)
                }
            };
            // The first ends' aggregates along an axis: `s` with `0 ≤ s < halves` whose fine
            // point `2s + r` and partner `2s + r + d` lie in the lattice.
            let range = |a: usize, n: isize, halves: isize| {
                let lo = (-(r[a] + d[a])).max(0);
                let lo = (lo + 1) / 2;
                let hi = (n - r[a]).min(n - r[a] - d[a]);
                let hi = ((hi + 1) / 2).min(halves);
                lo..hi.max(lo)
            };
            // This plane's targets are the first ends' aggregates shifted by `back`.
            let si = i as isize - back[0];
            if !range(0, nx, cx).contains(&si) {
                continue;
            }
            let (rows, columns) = (range(1, ny, cy), range(2, nz, cz));
            let fine_plane = 2 * si + r[0];
            for sj in rows {
                let j = sj + back[1];
                if !(0..cy).contains(&j) {
                    continue;
                }
                let fine_row = (fine_plane * ny + 2 * sj + r[1]) * nz + r[2];
                let first = e * n + part.fine + fine_row as usize;
                let row = ((entry as isize * cy + j) * cz + back[2]) as usize;
                let (lo, len) = (columns.start as usize, columns.len());
                if len == 0 {
                    continue;
                }
                for (o, b) in out.iter_mut().zip(blocks) {
                    // Every other slot (the fine points of one parity along the row).
                    let from = &b[first + 2 * lo..first + 2 * (lo + len) - 1];
                    for (o, pair) in o[row + lo..row + lo + len].iter_mut().zip(from.chunks(2)) {
                        *o += f64::from(pair[0]);
                    }
                }
            }
        }
    }
}
