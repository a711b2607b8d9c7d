//! The springs' part of the Newton matrix `A` in stencil order, for a fast `A·x`.
//!
//! Every spring of a lattice joins a point `p` to `p + offset(e)` for one of the 16 stencil
//! entries `e` ([`STENCIL`]), so its block can live at slot `e·n + p` of an array with a slot
//! for every point and entry (zero where there is no spring: across a hole, past the lattice's
//! edge). Then point `p`'s row of `A·x` is
//!
//! ```text
//! own[p]·x[p] + Σₑ Bₑ[p]·(x[p] − x[p + oₑ]) + Σₑ Bₑ[p − oₑ]·(x[p] − x[p − oₑ])
//! ```
//!
//! a sum of loops over contiguous arrays (the blocks and `x` stored as structure of arrays) that
//! vectorise on every SIMD tier, and each point's row is summed in the same order whoever
//! computes it: the points are split into ranges over threads and the result does not depend
//! on their number. Each entry's spring forces `Bₑ[q]·(x[q] − x[q + oₑ])` are computed once into
//! a buffer, then added to the rows of their first ends and taken from those of their second
//! (`−(B·(a − b))` is `B·(b − a)` to the bit): each block is read once, where reading it from
//! each end cost the 16³ benchmark at 1/60 s 10–15 % more per step (blocks do not fit in L2),
//! and the writes stay contiguous, where a loop over springs scatters them. The springs go in
//! tiles of [`TILE`] first ends, every entry of a tile before the next, so that a buffer of
//! forces is used while it is in the L1 cache (a whole range's forces of one entry, as before,
//! went through L2 three times: the kernel and the additions were 35 % of a resting 32³ cube's
//! step on one thread, 27 % after).
//!
//! The same slots hold each spring's rest length, stiffness and damping, from which the blocks
//! are assembled at every Newton iteration (its damper `d·u₀u₀ᵀ` along its direction at the
//! step's start as `c·L₀L₀ᵀ`, `c = d/|L₀|²`, `L₀` computed from the start positions): loops
//! over contiguous runs of slots that vectorise, where the loops over springs they replace
//! gathered and scattered by index. (The dampers' force in a residual is not a product here:
//! the force pass computes it with the springs' own, `crate::forces::Ties::Ignored`.)
//!
//! The blocks are assembled rounded to single precision, and the products of the solves to the
//! usual reductions (1e-2) are computed in it (`f32`, without fused multiply-adds, so the same
//! bits on every SIMD tier and thread count): such a product only steers the conjugate
//! gradients, whose direction Newton's method corrects at its next iteration, while the
//! residual that decides convergence (with the dampers' product in it) stays in double
//! precision. The rounding (a relative 6e-8 of each block and sum, times the condition of `A`
//! in the direction) is far below those reductions, but not below an exact solve's 1e-8: those
//! take [`Precision::Double`] (with single-precision exact solves, `leapfrog.w` at 1/60 s took
//! 58 steps in parts and 1 386 conjugate-gradient iterations a step instead of 15 and 382), for
//! which the blocks are computed again in double precision, once an assembly. Half the bytes
//! and twice the lanes: the 16³ benchmark's first 3 s at 1/60 s took 18 % less time on one
//! thread (a Zen 3 EPYC), its iteration counts unchanged; 8³ 25 % less. The diagonal and the
//! multigrid, which only precondition, are made from the rounded blocks too. The
//! single-precision solvers' products (the conjugate gradients' and GMRES's in `cg::single`) on
//! lattices of [`PACKED_FROM`] points or more read them once more, packed into 16 bits after
//! each assembly ([`packed`]): half the bytes again, for products bound by streaming their
//! blocks from memory.

mod kernels;
mod level;
mod packed;
#[cfg(test)]
mod tests;

pub(super) use level::{LevelStencil, COARSE_STENCIL};

pub(super) use kernels::dot_single;
use kernels::{
    out_rows_free, own_rows_soa, rows, spring_blocks, spring_blocks_single, spring_forces,
    spring_forces_single, Lane,
};

use packed::Packed;

use super::cg::{dot_chunk, sum_chunk};
use super::multigrid::Blocks;
use super::sym::{sym_mul, Sym};
use crate::compute::soa::Soa;
use crate::compute::team;
use crate::model::body::Body;
use crate::model::lattice::STENCIL;
use crate::model::Model;
use crate::vec3::Vec3;

/// Points per range below which a product is not split over threads. On 2 cores the 16³
/// benchmark's 4 096 points in two ranges step 5–23 % faster than in one (a Zen 3 EPYC,
/// 2026-11-27, medians of three sets of 4–16 alternated runs; with 4 096 here, as before, they
/// took one); 32³ 10–20 % faster.
pub(super) const MIN_POINTS_PER_RANGE: usize = 2048;

/// Points from which the single-precision solvers' products read the springs' blocks in 16 bits
/// ([`Packed`]; 6.3 MB of single-precision blocks): where the blocks fit in the caches, a
/// product does not wait for their bytes, and packing them costs a pass an assembly for nothing
/// (a 16³ cube thrown at 1/60 s on one thread of a 2-vCPU AMD EPYC with AVX2: 2.26 and 2.13×
/// real time with single-precision blocks, 2.25 and 2.05× with 16-bit ones).
const PACKED_FROM: usize = 16_384;

/// Springs per tile of a product (by their first ends, see [`kernels::rows`]): one stencil
/// entry's forces of a tile stay in the L1 cache (6 KB in single precision, 12 KB in double)
/// until they are added to their ends' rows.
const TILE: usize = 512;

/// One body's place in the model's arrays and its stencil offsets (flat index differences; 0
/// for an entry that needs an axis the lattice does not have).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Span {
    first: usize,
    len: usize,
    offset: [usize; 16],
}

impl Span {
    fn of(body: &Body) -> Span {
        let [_, ny, nz] = body.lattice().counts;
        let mut offset = [0; 16];
        for (o, (d, _)) in offset.iter_mut().zip(STENCIL) {
            let flat = (d[0] * ny as isize + d[1]) * nz as isize + d[2];
            *o = flat.max(0) as usize;
        }
        Span {
            first: body.points().start,
            len: body.len(),
            offset,
        }
    }
}

/// The springs' blocks of `A` by stencil slot (see the module documentation), with the buffers
/// of the product.
#[derive(Clone, Debug, Default)]
pub(super) struct SpringMatrix {
    n: usize,
    spans: Vec<Span>,
    /// Each spring's slot, in the order the springs were listed ([`SpringMatrix::push`]): slot
    /// order, which the solver keeps its springs in (the blocks it reads back by spring,
    /// [`SpringMatrix::assemble`], come from each array in order); while a list is made, how far
    /// it has come and whether it differs from the last.
    slot: Vec<u32>,
    cursor: usize,
    changed: bool,
    /// The blocks' six components (`[xx, yy, zz, xy, xz, yz]`), each `16·n` long, rounded to
    /// single precision (see the module documentation), and in double precision for exact
    /// solves: computed only when one asks for them after an assembly
    /// ([`SpringMatrix::double_blocks`]). Most steps have no exact solve, and writing and
    /// reading back the double-precision blocks was 40 % of an assembly's time (32³, one
    /// thread: 10.9 → 6.6 ms with the diagonal). Allocated from the start all the same: no
    /// step allocates.
    blocks_single: [Vec<f32>; 6],
    blocks: [Vec<f64>; 6],
    /// The single-precision blocks again in 16 bits, for the products of the single-precision
    /// solvers where `packing` (see [`Packed`]), made from the last assembly's blocks at the first
    /// such product after it (not `packed_current`). Empty below [`PACKED_FROM`] points.
    packed: Packed,
    packed_current: bool,
    packing: bool,
    /// Whether `blocks` are behind the last assembly, which was at `ends` with `[h, floor]`
    /// (the end positions as structure of arrays).
    double_behind: bool,
    ends: [Vec<f64>; 3],
    assembled_with: [f64; 2],
    /// The springs' rest lengths, stiffnesses and dampings by the same slots (0 where there is
    /// none).
    rest: Vec<f64>,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
    /// The points at the step's start, as structure of arrays: a damper acts along its
    /// spring's direction there, `d·uuᵀ = c·LLᵀ` with `L` the spring at the start and
    /// `c = d/|L|²`, computed from the points where a block is assembled rather than stored by
    /// slot.
    start: Soa,
    /// Each point's own block of `A` (its mass, walls, contacts: see [`SpringMatrix::set_own`]),
    /// and the same rounded to single precision as structure of arrays (`[xx, yy, zz, xy, xz,
    /// yz]`), from which a single-precision product's rows start vectorised: from the blocks of
    /// points and `x` in double precision, point by point, that took 4.8 % of a dropped 32³
    /// cube's step on one thread.
    own: Vec<Sym>,
    own_single: [Vec<f32>; 6],
    /// `x` as structure of arrays, and in single precision for the products with the blocks.
    x: [Vec<f64>; 3],
    x_single: [Vec<f32>; 3],
    /// The ranges of rows a product is split into (one per thread of the team).
    ranges: Ranges,
    /// Whether every slot array is still as `new` made it (zero).
    fresh: bool,
}

/// Whether a product loads its input `x` into its buffers ([`Input::Load`]), or finds it in
/// the single-precision one, where its caller put it ([`Input::Loaded`];
/// [`SpringMatrix::single_input`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Input {
    Load,
    Loaded,
}

/// The precision of a product with the springs' blocks (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Precision {
    /// Blocks, `x` and sums in `f32`: the products of solves to the usual reductions.
    Single,
    /// In `f64`: the products of exact solves.
    Double,
}

/// One range of rows of a product: where it starts, its rows of the product (structure of
/// arrays) and a buffer for the springs' forces of one stencil entry, for a product in double
/// precision (the dampers', an exact solve's) and for one in single precision.
#[derive(Clone, Debug, Default)]
struct RowRange {
    start: usize,
    y: [Vec<f64>; 3],
    forces: [Vec<f64>; 3],
    y_single: [Vec<f32>; 3],
    forces_single: [Vec<f32>; 3],
}

impl SpringMatrix {
    /// Sized for `model`, every block zero.
    pub fn new(model: &Model) -> Self {
        let n = model.point_count();
        SpringMatrix {
            n,
            spans: SpringMatrix::spans_of(model),
            slot: Vec::with_capacity(model.spring_count()),
            cursor: 0,
            changed: false,
            blocks_single: std::array::from_fn(|_| vec![0.0; 16 * n]),
            blocks: std::array::from_fn(|_| vec![0.0; 16 * n]),
            packed: if n >= PACKED_FROM {
                Packed::new(n)
            } else {
                Packed::default()
            },
            packed_current: false,
            packing: false,
            double_behind: false,
            ends: std::array::from_fn(|_| vec![0.0; n]),
            assembled_with: [0.0; 2],
            rest: vec![0.0; 16 * n],
            stiffness: vec![0.0; 16 * n],
            damping: vec![0.0; 16 * n],
            start: Soa::zeros(n),
            own: vec![[0.0; 6]; n],
            own_single: std::array::from_fn(|_| vec![0.0; n]),
            x: std::array::from_fn(|_| vec![0.0; n]),
            x_single: std::array::from_fn(|_| vec![0.0; n]),
            ranges: Ranges::default(),
            fresh: true,
        }
    }

    fn spans_of(model: &Model) -> Vec<Span> {
        model.bodies().iter().map(Span::of).collect()
    }

    /// True when sized for `model`'s bodies.
    pub fn fits(&self, model: &Model) -> bool {
        self.spans.len() == model.bodies().len()
            && self
                .spans
                .iter()
                .zip(model.bodies())
                .all(|(s, b)| *s == Span::of(b))
    }

    /// Starts the list of springs again (see [`SpringMatrix::push`] and
    /// [`SpringMatrix::finish`]).
    pub fn begin(&mut self) {
        self.cursor = 0;
        self.changed = false;
    }

    /// The next spring of the list: from flat point `a` along stencil entry `entry`. Springs
    /// come in slot order, `entry·n + a` increasing: entry by entry, and in each by first point
    /// (so the solver's order needs no sort: finding it for springs listed point by point took
    /// a sixth of a 32³ cube's setup).
    pub fn push(&mut self, a: usize, entry: usize) {
        let slot = (entry * self.n + a) as u32;
        assert!(
            self.cursor == 0 || self.slot[self.cursor - 1] < slot,
            "springs listed out of slot order"
        );
        match self.slot.get_mut(self.cursor) {
            Some(s) if *s == slot => {}
            Some(s) => (*s, self.changed) = (slot, true),
            None => (_, self.changed) = (self.slot.push(slot), true),
        }
        self.cursor += 1;
    }

    /// Ends the list. When it differs from the last one, every block is zeroed, so that no slot
    /// keeps the block of a spring no longer there.
    pub fn finish(&mut self) {
        if self.cursor != self.slot.len() {
            self.slot.truncate(self.cursor);
            self.changed = true;
        }
        // Fresh, they are zero already (and filling them touched 54 MB at 32³ on the leader
        // alone, a third of the first step's setup: 20 ms).
        if self.changed && !std::mem::take(&mut self.fresh) {
            self.blocks.iter_mut().for_each(|b| b.fill(0.0));
            self.blocks_single.iter_mut().for_each(|b| b.fill(0.0));
            self.rest.fill(0.0);
            self.stiffness.fill(0.0);
            self.damping.fill(0.0);
        }
    }

    /// Sets the block of spring `s` (its place in slot order).
    #[cfg(test)]
    fn set(&mut self, s: usize, block: &Sym) {
        let slot = self.slot[s] as usize;
        for ((c, single), &v) in self
            .blocks
            .iter_mut()
            .zip(&mut self.blocks_single)
            .zip(block)
        {
            (c[slot], single[slot]) = (v, v as f32);
        }
    }

    /// The products of the single-precision solvers with the blocks set by
    /// [`SpringMatrix::set`] in 16 bits, whatever the size.
    #[cfg(test)]
    fn pack(&mut self) {
        self.packed = Packed::new(self.n);
        (self.packing, self.packed_current) = (true, false);
    }

    /// Sets spring `s` (its place in slot order): rest length, stiffness and damping.
    pub fn set_spring(&mut self, s: usize, rest: f64, stiffness: f64, damping: f64) {
        let slot = self.slot[s] as usize;
        (self.rest[slot], self.stiffness[slot]) = (rest, stiffness);
        self.damping[slot] = damping;
    }

    /// The step's start `x0`, along whose springs the dampers act.
    pub fn start_dampers(&mut self, x0: &[Vec3]) {
        let size = team::chunk_size(x0.len(), MIN_POINTS_PER_RANGE);
        team::for_each_chunk(self.start.parts_mut(), size, &|chunk, [x, y, z]| {
            for (i, p) in x0[chunk * size..].iter().take(x.len()).enumerate() {
                (x[i], y[i], z[i]) = (p.x, p.y, p.z);
            }
        });
    }

    /// The springs' directions at the step's start ([`SpringMatrix::start_dampers`]) into
    /// `directions`, by spring (in slot order).
    pub fn start_directions(&self, directions: &mut [Vec3]) {
        let (start, slots, spans, n) = (&self.start, &self.slot, &self.spans[..], self.n);
        let size = team::chunk_size(directions.len(), MIN_POINTS_PER_RANGE);
        let (x, y, z) = (start.x(), start.y(), start.z());
        team::for_each_chunk([directions], size, &|chunk, [directions]| {
            // The slots rise through the chunk: its springs' entry and body are followed as
            // they change, not found again for each (a division and a search a spring were
            // most of this pass).
            let (mut e, mut span) = (usize::MAX, 0);
            let (mut entry_start, mut entry_end) = (0, 0);
            for (u, &slot) in directions.iter_mut().zip(&slots[chunk * size..]) {
                let slot = slot as usize;
                if slot >= entry_end {
                    e = slot / n;
                    (entry_start, entry_end, span) = (e * n, (e + 1) * n, 0);
                }
                let q = slot - entry_start;
                while spans[span].first + spans[span].len <= q {
                    span += 1;
                }
                let b = q + spans[span].offset[e];
                let l = Vec3::new(x[q] - x[b], y[q] - y[b], z[q] - z[b]);
                let length = l.length();
                *u = if length > 0.0 { l / length } else { Vec3::ZERO };
            }
        });
    }

    /// The springs' blocks of `A` at the end positions `x0 + h·v` (see [`spring_blocks`];
    /// `floor` bounds `1 − rest/l` from below) in single precision.
    pub fn assemble(&mut self, x0: &[Vec3], v: &[Vec3], h: f64, floor: f64) {
        self.load_end_positions(x0, v, h);
        (self.double_behind, self.assembled_with) = (true, [h, floor]);
        self.compute_blocks(Precision::Single);
        self.packed_current = false;
    }

    /// Whether the single-precision solvers' products may read the blocks in 16 bits (they do
    /// from [`PACKED_FROM`] points on): not where the step's field swirls, whose solves converge
    /// linearly at best and ask more of each direction (`leapfrog.w` at 1/60 s took twice the
    /// Newton iterations with them).
    pub fn pack_products(&mut self, may: bool) {
        self.packing = may && self.n >= PACKED_FROM;
    }

    /// Whether the single-precision solvers' products read the blocks in 16 bits.
    #[cfg(test)]
    pub fn packs_products(&self) -> bool {
        self.packing
    }

    /// The single-precision blocks of the last assembly by spring (in slot order), as the
    /// multigrid's fine level reads them.
    pub fn blocks_by_spring(&self) -> Blocks<'_> {
        Blocks::Slots {
            slots: &self.slot,
            components: &self.blocks_single,
        }
    }

    /// The double-precision blocks of the last assembly, where they are behind it: from its end
    /// positions and the dampers' start as it is now (a step whose first Newton iteration
    /// keeps the last step's `A` has new ones, and its exact solves take them).
    fn double_blocks(&mut self) {
        if std::mem::take(&mut self.double_behind) {
            self.compute_blocks(Precision::Double);
        }
    }

    /// The blocks at the assembly's end positions into the slot arrays of `precision`.
    fn compute_blocks(&mut self, precision: Precision) {
        let (xs, n, [h, floor]) = (&self.ends, self.n, self.assembled_with);
        let (start, rest, stiffness, damping) =
            (&self.start, &self.rest, &self.stiffness, &self.damping);
        let (double, single) = (&mut self.blocks, &mut self.blocks_single);
        for_each_run(&self.spans, |e, q, len, o| {
            let at = e * n + q;
            // The run in chunks over the team (each slot's block depends on its slot alone).
            let size = team::chunk_size(len, MIN_POINTS_PER_RANGE);
            let inputs = |chunk: usize, len: usize| {
                let (at, q) = (at + chunk * size, q + chunk * size);
                let springs = [
                    &rest[at..at + len],
                    &stiffness[at..at + len],
                    &damping[at..at + len],
                ];
                let ends = (part(xs, q, len), part(xs, q + o, len));
                let start_ends = (start.range(q..q + len), start.range(q + o..q + o + len));
                (ends, start_ends, springs)
            };
            match precision {
                Precision::Single => {
                    let b = single.each_mut().map(|b| &mut b[at..at + len]);
                    team::for_each_chunk(b, size, &|chunk, b| {
                        let (ends, start, springs) = inputs(chunk, b[0].len());
                        spring_blocks_single(b, ends, start, springs, [h, floor]);
                    });
                }
                Precision::Double => {
                    let b = double.each_mut().map(|b| &mut b[at..at + len]);
                    team::for_each_chunk(b, size, &|chunk, b| {
                        let (ends, start, springs) = inputs(chunk, b[0].len());
                        spring_blocks(b, ends, start, springs, [h, floor]);
                    });
                }
            }
        });
    }

    /// `x0 + h·v` into `ends`.
    fn load_end_positions(&mut self, x0: &[Vec3], v: &[Vec3], h: f64) {
        let [p0, p1, p2] = &mut self.ends;
        let size = team::chunk_size(x0.len(), MIN_POINTS_PER_RANGE);
        team::for_each_chunk([p0, p1, p2], size, &|chunk, [p0, p1, p2]| {
            let at = chunk * size;
            for (i, (&x, &v)) in x0[at..].iter().zip(&v[at..]).take(p0.len()).enumerate() {
                let p = x + v * h;
                (p0[i], p1[i], p2[i]) = (p.x, p.y, p.z);
            }
        });
    }

    /// The points' own blocks of `A` ([`SpringMatrix::apply`], [`SpringMatrix::diagonal`]).
    pub fn set_own(&mut self, own: &[Sym]) {
        let size = team::chunk_size(own.len(), MIN_POINTS_PER_RANGE);
        let [a, b, c, d, e, f] = &mut self.own_single;
        let parts = ([&mut self.own[..]], [a, b, c, d, e, f].map(|s| &mut s[..]));
        team::for_each_chunk_pair(parts, size, &|chunk, ([double], mut single)| {
            let own = &own[chunk * size..chunk * size + double.len()];
            double.copy_from_slice(own);
            for (i, own) in own.iter().enumerate() {
                for (single, &o) in single.iter_mut().zip(own) {
                    single[i] = o as f32;
                }
            }
        });
    }

    /// `y = (own·x + springs·x)`, then scaled by `free` per point, `own` the points' blocks
    /// ([`SpringMatrix::set_own`]); the springs' part, and in single precision `own·x` too, in
    /// `precision` (see the module documentation).
    pub fn apply(&mut self, free: &[f64], x: &[Vec3], y: &mut [Vec3], precision: Precision) {
        self.apply_with(free, x, y, precision, Input::Load, None);
    }

    /// [`SpringMatrix::apply`] and [`SpringMatrix::apply_dot`]: `x` loaded into the product's
    /// buffers or already there, `x·y` summed into `dot` where given (else 0 returned).
    fn apply_with(
        &mut self,
        free: &[f64],
        x: &[Vec3],
        y: &mut [Vec3],
        precision: Precision,
        input: Input,
        dot: Option<&mut [f64]>,
    ) -> f64 {
        if precision == Precision::Double {
            self.double_blocks();
        }
        let blocks = (&self.blocks, &self.blocks_single);
        let buffers = (&mut self.x, &mut self.x_single);
        let (spans, n) = (&self.spans[..], self.n);
        let out = |p: usize, row: Vec3| row * free[p];
        product(
            &mut self.ranges,
            (spans, n),
            blocks,
            buffers,
            (&self.own, Some(&self.own_single)),
            (x, input),
            precision,
            y,
            &out,
            dot,
        )
    }

    /// The dampers' start positions ([`SpringMatrix::start_dampers`]).
    pub fn start(&self) -> &Soa {
        &self.start
    }

    /// The input of the next single-precision [`SpringMatrix::apply_dot`]: `x` rounded to
    /// single precision, as structure of arrays, written by the caller (the conjugate
    /// gradients, as they update their direction).
    pub fn single_input(&mut self) -> [&mut [f32]; 3] {
        self.x_single.each_mut().map(|x| &mut x[..])
    }

    /// [`SpringMatrix::apply`], returning `x·y` summed as [`super::cg::dot`] sums it (into
    /// `sums`, one per chunk of [`sum_chunk`] points): the same bits, without a pass of its own.
    /// In single precision, `x` must be in [`SpringMatrix::single_input`] already.
    pub fn apply_dot(
        &mut self,
        free: &[f64],
        x: &[Vec3],
        y: &mut [Vec3],
        precision: Precision,
        sums: &mut [f64],
    ) -> f64 {
        self.apply_with(free, x, y, precision, Input::Loaded, Some(sums))
    }

    /// `y = own·p + springs·p` in single precision (the springs' blocks in 16 bits where
    /// [`SpringMatrix::pack_products`] allows), scaled by `free` per point, as structure of
    /// arrays, `p` in [`SpringMatrix::single_input`] already (the single-precision conjugate
    /// gradients' direction); returns `p·y` (in double precision), each chunk of [`sum_chunk`]
    /// points summed in order into `sums`, then the chunks' sums in order: the same bits on any
    /// number of threads.
    pub fn apply_dot_single(&mut self, free: &[f64], y: [&mut [f32]; 3], sums: &mut [f64]) -> f64 {
        self.apply_single_with(free, y, Some(sums))
    }

    /// [`SpringMatrix::apply_dot_single`] without the dot product (single-precision GMRES).
    pub fn apply_single(&mut self, free: &[f64], y: [&mut [f32]; 3]) {
        self.apply_single_with(free, y, None);
    }

    /// [`SpringMatrix::apply_dot_single`], `p·y` summed into `sums` where given (else 0
    /// returned).
    fn apply_single_with(
        &mut self,
        free: &[f64],
        y: [&mut [f32]; 3],
        sums: Option<&mut [f64]>,
    ) -> f64 {
        let (spans, n) = (&self.spans[..], self.n);
        self.ranges.fit(n, spans);
        if self.packing && !std::mem::replace(&mut self.packed_current, true) {
            self.packed.pack(&self.blocks_single, n);
        }
        let (own, x) = (&self.own_single, &self.x_single);
        let init = |start: usize, out: [&mut [f32]; 3]| {
            let len = out[0].len();
            own_rows_soa(part(own, start, len), part(x, start, len), out);
        };
        if self.packing {
            let forces = self.packed.entry_forces(n);
            ranges_rows(&mut self.ranges.0, spans, n, &init, x, &forces);
        } else {
            let forces = entry_forces(spring_forces_single, &self.blocks_single);
            ranges_rows(&mut self.ranges.0, spans, n, &init, x, &forces);
        }
        let ranges = &self.ranges;
        // Rows `lo .. lo + y.len()` of the product out of the ranges that hold them.
        let rows_out = |lo: usize, [y0, y1, y2]: [&mut [f32]; 3]| {
            for (range, rows) in ranges.holding(lo, lo + y0.len()) {
                let at = rows.start - range.start..rows.end - range.start;
                let (a, b) = (rows.start - lo, rows.end - lo);
                let out = [&mut y0[a..b], &mut y1[a..b], &mut y2[a..b]];
                let rows_of = range.y_single.each_ref().map(|r| &r[at.clone()]);
                out_rows_free(rows_of, &free[rows], out);
            }
        };
        let size = sum_chunk(n);
        let Some(sums) = sums else {
            team::for_each_chunk(y, size, &|c, y| rows_out(c * size, y));
            return 0.0;
        };
        team::for_each_chunk_into(y, size, sums, &|c, [y0, y1, y2]| {
            // The chunk's rows, then its sum in one pass while they are in the cache (the
            // ranges, one per thread, do not decide its order).
            let lo = c * size;
            rows_out(lo, [&mut *y0, &mut *y1, &mut *y2]);
            let hi = lo + y0.len();
            dot_single(x.each_ref().map(|x| &x[lo..hi]), [&*y0, &*y1, &*y2])
        });
        sums.iter().sum()
    }

    /// The diagonal blocks of `A`'s springs' part plus the points' own ([`SpringMatrix::set_own`])
    /// into `diag`, from the blocks in
    /// single precision (the diagonal serves the preconditioner): each point's `own`, then the
    /// block of each stencil entry's spring from it, then of each entry's spring to
    /// it, in the entries' order. Each point's sum is taken in that order whoever computes it
    /// (the points in chunks over the team); every block is read from its slot in order, where
    /// a gather by each point's springs read it twice, far apart (5 % of the 16³ benchmark's
    /// samples on 2 threads). Compiled for each SIMD tier: for the baseline alone it took
    /// 2.3–2.9 ms of a 32³ cube's assembly on one thread, 1.5 ms with AVX-512.
    pub fn diagonal(&self, diag: &mut [Sym]) {
        let (spans, blocks, n, own) = (&self.spans[..], &self.blocks_single, self.n, &self.own);
        let size = team::chunk_size(n, MIN_POINTS_PER_RANGE);
        team::for_each_chunk([diag], size, &|chunk, [diag]| {
            diagonal_chunk(spans, blocks, n, own, chunk * size, diag);
        });
    }
}

crate::compute::simd::multiversion! {
    /// [`SpringMatrix::diagonal`]'s sums for the points `start .. start + diag.len()`.
    fn diagonal_chunk(
        spans: &[Span],
        blocks: &[Vec<f32>; 6],
        n: usize,
        own: &[Sym],
        start: usize,
        diag: &mut [Sym],
    ) {
        // Points per pass over the entries: their sums, component by component, stay in the L1
        // cache, and each pass adds two contiguous runs (vectorised).
        const BLOCK: usize = 256;
        let mut sums = [[0.0; BLOCK]; 6];
        for (b, diag) in diag.chunks_mut(BLOCK).enumerate() {
            let (p0, p1) = (start + b * BLOCK, start + b * BLOCK + diag.len());
            for (i, own) in own[p0..p1].iter().enumerate() {
                for (sum, &o) in sums.iter_mut().zip(own) {
                    sum[i] = o;
                }
            }
            // The blocks at slots `base + p − back` for the points `p` of `from .. to`.
            let mut add = |(from, to): (usize, usize), base: usize, back: usize| {
                if from < to {
                    for (sum, block) in sums.iter_mut().zip(blocks) {
                        let block = &block[base + from - back..base + to - back];
                        for (s, &b) in sum[from - p0..to - p0].iter_mut().zip(block) {
                            *s += f64::from(b);
                        }
                    }
                }
            };
            for span in spans {
                let (first, end) = (span.first, span.first + span.len);
                let entries = span.offset.iter().enumerate();
                let entries = entries.filter(|&(_, &o)| o != 0 && o < span.len);
                // From each point: slot `e·n + p`, where the partner `p + o` is in the body.
                for (e, &o) in entries.clone() {
                    add((p0.max(first), p1.min(end - o)), e * n, 0);
                }
                // To each point: slot `e·n + p − o`, for the points `p ≥ first + o`.
                for (e, &o) in entries {
                    add((p0.max(first + o), p1.min(end)), e * n, o);
                }
            }
            for (i, d) in diag.iter_mut().enumerate() {
                *d = std::array::from_fn(|c| sums[c][i]);
            }
        }
    }
}

/// The ranges of rows a product is split into, one per thread of the team.
#[derive(Clone, Debug, Default)]
struct Ranges(Vec<RowRange>);

impl Ranges {
    /// Rows of the first range of the last product (the others may have fewer).
    fn size(&self) -> usize {
        self.0.first().map_or(1, |r| r.y[0].len().max(1))
    }

    /// The ranges that hold rows of `lo .. hi`, each with the rows of them it holds.
    fn holding(
        &self,
        lo: usize,
        hi: usize,
    ) -> impl Iterator<Item = (&RowRange, std::ops::Range<usize>)> {
        self.0.iter().filter_map(move |range| {
            let len = range.y[0].len();
            let rows = lo.max(range.start)..hi.min(range.start + len);
            (!rows.is_empty()).then_some((range, rows))
        })
    }

    /// Sized for a product over the `n` rows of the bodies `spans` (anew, allocating, only when
    /// the ranges change).
    fn fit(&mut self, n: usize, spans: &[Span]) {
        let (starts, count) = Ranges::starts(n, spans);
        let starts = &starts[..count];
        let same = self.0.len() == count
            && self.0.iter().zip(starts).all(|(r, &s)| r.start == s)
            && self.0.iter().map(|r| r.y[0].len()).sum::<usize>() == n;
        if same {
            return;
        }
        // Each range's spring forces of one stencil entry in one tile.
        let room = TILE;
        self.0 = (starts.iter().enumerate())
            .map(|(r, &start)| {
                let rows = starts.get(r + 1).unwrap_or(&n) - start;
                RowRange {
                    start,
                    y: std::array::from_fn(|_| vec![0.0; rows]),
                    forces: std::array::from_fn(|_| vec![0.0; room]),
                    y_single: std::array::from_fn(|_| vec![0.0; rows]),
                    forces_single: std::array::from_fn(|_| vec![0.0; room]),
                }
            })
            .collect();
    }

    /// The first rows of the ranges of a product over `n` rows (the first `count` of the array
    /// returned, with `count`): one range a thread, each with as many blocks to read. A range
    /// that starts inside a body also computes the springs that reach its first rows from
    /// before it (as many a stencil entry as its offset, about 2 % of a 32³ lattice's), so the
    /// first range, which has none, takes that many more rows: with equal rows, the leader,
    /// whose range is the first, waited for the helper at every product.
    fn starts(n: usize, spans: &[Span]) -> ([usize; team::OWNED_ITEMS], usize) {
        let count = (team::threads().min(n / MIN_POINTS_PER_RANGE)).clamp(1, team::OWNED_ITEMS);
        // The springs before row `b` that reach it or later, in rows' worth of blocks.
        let halo = |b: usize| -> usize {
            let reaching = |s: &Span| {
                let inside = s.first < b && b < s.first + s.len;
                let before = b.saturating_sub(s.first);
                let offsets = s.offset.iter().filter(|&&o| o != 0 && o < s.len);
                offsets.map(|&o| o.min(before)).sum::<usize>() * usize::from(inside)
            };
            spans.iter().map(reaching).sum::<usize>() / STENCIL.len()
        };
        // Each boundary's halo where the rows split evenly.
        let halos = |r: usize| halo(r * n / count);
        let work = (n + (1..count).map(halos).sum::<usize>()) / count;
        let mut starts = [0; team::OWNED_ITEMS];
        let mut next = work;
        for r in 1..count {
            starts[r] = next.min(n).max(starts[r - 1]);
            next = starts[r] + work.saturating_sub(halos(r));
        }
        (starts, count)
    }
}

/// The product of the blocks (in both precisions; by slot `e·n + p` of the `spans`' stencil
/// entries) and `own` (and, where given, its copy in single precision, which a single-precision
/// product then takes) with `x` in `precision`, into `y` through `out(p, row)`; `buffers` hold
/// `x` in each precision (loaded here unless `input` says the single-precision one holds it
/// already, for a single-precision product). With `dot`, returns `x·y` summed as `cg::dot` sums it (its chunks' sums into
/// `dot`), else 0.
#[allow(clippy::too_many_arguments)]
fn product(
    ranges: &mut Ranges,
    (spans, n): (&[Span], usize),
    (blocks, blocks_single): (&[Vec<f64>; 6], &[Vec<f32>; 6]),
    (x_double, x_single): (&mut [Vec<f64>; 3], &mut [Vec<f32>; 3]),
    (own, own_single): (&[Sym], Option<&[Vec<f32>; 6]>),
    (x, input): (&[Vec3], Input),
    precision: Precision,
    y: &mut [Vec3],
    out: &(impl Fn(usize, Vec3) -> Vec3 + Sync),
    dot: Option<&mut [f64]>,
) -> f64 {
    ranges.fit(n, spans);
    let own_x = |p: usize| sym_mul(&own[p], x[p]);
    if precision == Precision::Single {
        if input == Input::Load {
            load(x_single, x);
        }
        let forces = entry_forces(spring_forces_single, blocks_single);
        let xs = &*x_single;
        let init = |start: usize, out: [&mut [f32]; 3]| match own_single {
            Some(own) => {
                let len = out[0].len();
                own_rows_soa(part(own, start, len), part(xs, start, len), out);
            }
            None => f32::own_rows(start, &own_x, out),
        };
        ranges_rows(&mut ranges.0, spans, n, &init, x_single, &forces);
    } else {
        load(x_double, x);
        let forces = entry_forces(spring_forces, blocks);
        let init = |start: usize, out: [&mut [f64]; 3]| f64::own_rows(start, &own_x, out);
        ranges_rows(&mut ranges.0, spans, n, &init, x_double, &forces);
    }
    let ranges = &*ranges;
    // Rows `lo .. lo + y.len()` of the product out of the ranges that hold them.
    let rows_out = |lo: usize, y: &mut [Vec3]| {
        for (range, rows) in ranges.holding(lo, lo + y.len()) {
            let (a, b) = (rows.start, rows.end);
            let (at, y) = (a - range.start, &mut y[a - lo..b - lo]);
            match precision {
                Precision::Single => {
                    let rows = range.y_single.each_ref().map(|r| &r[at..at + y.len()]);
                    f32::out_rows(a, rows, out, y);
                }
                Precision::Double => {
                    let rows = range.y.each_ref().map(|r| &r[at..at + y.len()]);
                    f64::out_rows(a, rows, out, y);
                }
            }
        }
    };
    let Some(sums) = dot else {
        team::for_each_chunk([y], ranges.size(), &|r, [y]| rows_out(r * ranges.size(), y));
        return 0.0;
    };
    // With `x·y` summed as `cg::dot` sums it (the same chunks, each in order; the same bits),
    // each chunk's rows while they are in the cache, where a pass of its own read `x` and `y`
    // again.
    let size = sum_chunk(n);
    team::for_each_chunk_into([y], size, sums, &|c, [y]| {
        rows_out(c * size, y);
        dot_chunk(&x[c * size..c * size + y.len()], y)
    });
    sums.iter().sum()
}

/// Each range's [`rows`] over the team, into its buffers of `T`'s precision.
fn ranges_rows<T: Lane>(
    ranges: &mut [RowRange],
    spans: &[Span],
    n: usize,
    init: &(impl Fn(usize, [&mut [T]; 3]) + Sync),
    x: &[Vec<T>; 3],
    entry_forces: &(impl Fn(usize, usize, usize, [&mut [T]; 3], [&[T]; 3], [&[T]; 3]) + Sync),
) {
    team::for_each_mut(ranges, &|_, range| {
        let start = range.start;
        let ([y0, y1, y2], forces) = T::buffers(range);
        let out = [&mut y0[..], &mut y1[..], &mut y2[..]];
        rows(spans, n, init, x, start, out, forces, TILE, entry_forces);
    });
}

/// `x` into the structure of arrays `soa` (rounded to its precision), over the team.
fn load<T: Lane>(soa: &mut [Vec<T>; 3], x: &[Vec3]) {
    let [x0, x1, x2] = soa;
    let size = team::chunk_size(x.len(), MIN_POINTS_PER_RANGE);
    team::for_each_chunk([x0, x1, x2], size, &|chunk, soa| {
        T::load(&x[chunk * size..], soa)
    });
}

/// Calls `f(e, q, len, o)` for each run of slots of stencil entry `e` (offset `o`) that may hold
/// a spring: its first ends `q .. q + len` of one body, whose second ends `q + o ..` are in the
/// body too.
fn for_each_run(spans: &[Span], mut f: impl FnMut(usize, usize, usize, usize)) {
    for span in spans {
        for (e, &o) in span.offset.iter().enumerate() {
            if o != 0 && o < span.len {
                f(e, span.first, span.len - o, o);
            }
        }
    }
}

/// The `entry_forces` of [`rows`] for a kernel `kernel(f, x, xn, parts)` over the slot arrays
/// `arrays` (the blocks, in either precision).
#[allow(clippy::type_complexity)]
fn entry_forces<'a, T, const C: usize>(
    kernel: fn([&mut [T]; 3], [&[T]; 3], [&[T]; 3], [&[T]; C]),
    arrays: &'a [Vec<T>; C],
) -> impl Fn(usize, usize, usize, [&mut [T]; 3], [&[T]; 3], [&[T]; 3]) + Sync + 'a
where
    T: Sync,
{
    move |at, _, _, f, x, xn| {
        let len = f[0].len();
        kernel(f, x, xn, part(arrays, at, len));
    }
}

/// `arrays[c][at .. at + len]` for each `c`.
fn part<T, const C: usize>(arrays: &[Vec<T>; C], at: usize, len: usize) -> [&[T]; C] {
    std::array::from_fn(|c| &arrays[c][at..at + len])
}
