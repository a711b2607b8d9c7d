//! The preconditioner of the conjugate gradients: a multigrid V-cycle over aggregates of the
//! lattice.
//!
//! Preconditioned by `A`'s diagonal blocks alone, conjugate gradients need many iterations for
//! the smooth modes of `A = M + h·D₀ + h²·K` (a body moving as a whole is the smoothest: `A` is
//! only `M` there, while its diagonal also holds every spring's stiffness), and more as the
//! lattice grows. A coarse copy of `A` solves those modes in few unknowns.
//!
//! Every level has the form of the fine one: a symmetric 3×3 block `own` per node and, per
//! coupled pair of nodes `(a, c)`, a block `B` that adds `[[B, −B], [−B, B]]` to `A` (a spring's
//! stiffness and damping, a contact's). The nodes of the next level are the aggregates of
//! 2×2×2 nodes of one body's lattice (coordinates halved), and its operator is the Galerkin
//! product `PᵀAP` with `P` constant over each aggregate: an aggregate's `own` is the sum of its
//! nodes' (plus the blocks of pairs to held points), a pair inside an aggregate cancels, and the
//! pairs between two aggregates add into one block. So the coarse levels are mass-spring
//! systems too, built with the same loops down to one node per body.
//!
//! On the fine level the preconditioner is additive: `z = ω·D⁻¹·r + P·(coarse solve of Pᵀ·r)`,
//! which costs no product with `A` (a V-cycle's smoothing there took two per iteration and
//! saved fewer conjugate-gradient iterations than that: 16³ benchmark, 60 steps at 1/60 s, 3 312
//! iterations in 2.2 s against 2 074 in 3.6 s). There `P` is trilinear over each large full
//! lattice ([`trilinear`]), a smooth correction, and constant over the aggregates of the
//! others. The coarse levels, an eighth of the size each, are solved by a V-cycle that smooths
//! with over-relaxed block Jacobi ([`OMEGA`]) before and after the next level's correction (the
//! same smoother on both sides, so the preconditioner is symmetric, as conjugate gradients
//! need), a large level taking that correction scaled up ([`OVER_CORRECTION`]); the coarsest by
//! a few Jacobi sweeps. A coarse level's residual
//! `r − A·e` is a product in stencil order ([`LevelStencil`]: the aggregates of a lattice form a
//! lattice), in single precision where the fine products are, with the pairs found at the
//! iterate added after; on a level of small lattices ([`STENCIL_NODES`]), a loop over its list of
//! pairs. Its loops over nodes and pairs are spread over the step's team
//! ([`crate::compute::team`]) where a level is large enough, each node's and coarse pair's sums
//! gathered in the order of the nodes and pairs (the order a single thread's scatter adds them
//! in): the same bits on any number of threads. Its buffers are sized when it is built and
//! reused.

mod galerkin;
mod trilinear;

use super::cg::sum_chunk;
use super::stencil::{dot_single, LevelStencil, Precision};
use super::sym::{add_sym, sym_inverse, sym_mul, Sym};
use crate::compute::team;
use crate::model::Model;
use crate::vec3::Vec3;
use galerkin::Galerkin;
use trilinear::Transfer;

/// A node of a level: its body and its lattice coordinates (halved on each coarser level).
type Node = (u32, [u32; 3]);

/// A pair inside one aggregate (it has no block on the next level).
const INSIDE: u32 = u32::MAX;

/// Weight of the Jacobi smoother on the coarse levels: over-relaxed. Conjugate-gradient
/// iterations a step, BackwardEuler at 1/60 s over the frame-rate job's time, 0.9 → 1.2: a 32³
/// cube dropped on a floor 10.52 → 9.15, resting on it 5.23 → 4.50, at 16³ 3.78 → 3.49 and
/// 1.92 → 1.78 (4–7 % faster on an AMD EPYC, one and two threads); the corpus at 1/60 s 5 %
/// fewer in all (two of its 113 worlds more: `custom-IPC.w` 112 → 128 a step,
/// `moveLeft_Euler_with_small_force.w` 42 → 57). From 1.05 to 1.4 the jobs differ by a few per
/// cent; at 1.6 the smoother diverges on their levels, the cycle is no longer positive definite
/// and the diagonal preconditions alone (75 iterations a step dropped); `pile.toml` (many small
/// bodies pressed together) already at 1.2, where a cycle that turns out indefinite is damped
/// ([`OMEGA_DAMPED`]). Not where a field swirls.
const OMEGA: f64 = 1.2;

/// [`OMEGA`] where the step's field swirls (GMRES on a crushed lattice: `leapfrog.w` at 1/60 s
/// took 578 conjugate-gradient or GMRES iterations a step at 1.05, 850 at 0.9 and 4 938 at 1.1,
/// with 33–54 Newton iterations), and for the rest of a step from a solve whose over-relaxed
/// cycle the conjugate gradients found not positive definite (`pile.toml` at 1/60 s, its first
/// 0.5 s: 511 iterations a step at 0.9, 479 at 1.1, 2 746 at 1.2 without this fallback, 515
/// with it; damped until the levels were built again instead, the corpus took 354 132
/// iterations, 343 758 so).
const OMEGA_DAMPED: f64 = 0.9;

/// Weight of the fine level's block Jacobi, added to the coarse correction.
const FINE_OMEGA: f64 = 0.7;

/// Nodes per lattice, on average, from which a coarse level's products run in stencil order
/// ([`LevelStencil`]): below, a product walks so many short runs of slots (a pile of small
/// bodies: a few dozen nodes a lattice, 13 entries each) that the list of pairs is faster
/// (`pile.toml` under backward Euler at 1/60 s, 1 s: 7 % slower in stencil order at every level).
const STENCIL_NODES: usize = 512;

/// The factor of a coarse level's correction on a level of [`OVER_CORRECTED_NODES`] or more.
/// A correction constant over each aggregate (the prolongation here) underestimates the smooth
/// error it corrects, the more so the further down it comes from, and scaled up it corrects
/// more (the over-correction of aggregation multigrid; with the same smoother before and after
/// it the cycle stays symmetric, and positive below 2). Conjugate-gradient iterations a step,
/// BackwardEuler at 1/60 s over the first second (2 threads, AMD EPYC with AVX-512), 1.0 → 1.4:
/// a 32³ cube resting on a floor 17.0 → 14.0, dropped on it 26.1 → 22.6, at 16³ 7.2 → 6.6 and
/// 10.3 → 9.5 (1.3 and 1.5 did less); at 64³ 22.5 and 32.6, from 24.0 and 33.8 with the
/// W-cycle that the 64³ cube's first coarse level took before (its correction twice; with both,
/// 31.6 at 1.3: the correction overshoots), 0.061 → 0.065× and 0.041 → 0.045× real time. On
/// levels of small lattices it changes little and costs the hardest worlds of the corpus (8³,
/// levels of 64 nodes and fewer; `leapfrog.w` took 42 % more at 1.3), so they keep theirs.
const OVER_CORRECTION: f64 = 1.4;

/// [`OVER_CORRECTION`] where the fine level's transfers are trilinear (see [`trilinear`]):
/// conjugate-gradient iterations a step, BackwardEuler at 1/60 s over the job's time (2
/// threads, Intel Xeon with AVX-512), 1.4 → 1.7 → 2.0: a 32³ cube resting on a floor 10.2 →
/// 10.1 → 10.2, dropped on it 15.1 → 13.8 → 14.4; at 16³ 4.5 → 4.4 → 4.4 and 6.0 → 6.1 → 6.1.
const OVER_CORRECTION_TRILINEAR: f64 = 1.7;

/// Nodes from which a coarse level takes the next one's correction times
/// [`OVER_CORRECTION`].
const OVER_CORRECTED_NODES: usize = 512;

/// Nodes below which a coarse level and those under it are cycled by one thread (see `cycle`).
const SERIAL_NODES: usize = 1024;

/// Jacobi sweeps on the coarsest level (one node per body: exact for a body alone).
const COARSEST_SWEEPS: usize = 4;

/// One level's operator `A = blockdiag(own) + Σ [[B, −B], [−B, B]]` over its coupled pairs,
/// with the inverses of its diagonal blocks.
pub(super) struct Operator<'a> {
    pub own: &'a [Sym],
    /// The pairs that stay from step to step (springs) and their blocks…
    pub pairs: &'a [[u32; 2]],
    pub blocks: Blocks<'a>,
    /// …and those found at the iterate (contacts between bodies).
    pub more_pairs: &'a [[u32; 2]],
    pub more_blocks: &'a [Sym],
    pub diag_inv: &'a [Sym],
    /// Per node 1 when it moves, 0 when held (the finest level only; the coarse levels hold
    /// moving nodes alone).
    pub free: Option<&'a [f64]>,
}

/// The blocks of a level's pairs, pair by pair.
#[derive(Clone, Copy)]
pub(super) enum Blocks<'a> {
    /// A block per pair (the coarse levels').
    Listed(&'a [Sym]),
    /// Pair `k`'s block at `slots[k]` of the six single-precision component arrays of the
    /// springs' stencil-ordered matrix (the fine level's: see `SpringMatrix`), read there
    /// rather than copied into a block per pair at every assembly (the copy, 24 MB at 32³,
    /// took 3.5 ms of a 15 ms assembly on one thread).
    Slots {
        slots: &'a [u32],
        components: &'a [Vec<f32>; 6],
    },
}

impl Blocks<'_> {
    /// Pair `k`'s block.
    #[inline(always)]
    pub(super) fn get(&self, k: usize) -> Sym {
        match self {
            Blocks::Listed(blocks) => blocks[k],
            Blocks::Slots { slots, components } => {
                let slot = slots[k] as usize;
                std::array::from_fn(|c| f64::from(components[c][slot]))
            }
        }
    }
}

/// Each node's pairs, in the order of the pairs: those of node `a` are
/// `pairs[start[a] .. start[a + 1]]`, each a pair's index, with [`SECOND_END`] set where `a`
/// is its second end.
#[derive(Clone, Debug, Default)]
pub(super) struct Incidence {
    start: Vec<u32>,
    pairs: Vec<u32>,
}

/// Marks a pair of [`Incidence`] whose second end the node is.
const SECOND_END: u32 = 1 << 31;

/// Fewest nodes in a chunk of a loop over one level's nodes spread over threads.
const MIN_NODES: usize = 128;

/// Items per thread of [`restrict_operator`]'s loop over coarse pairs, whose sizes differ.
const PAIR_ITEMS_PER_THREAD: usize = 8;

impl Incidence {
    fn of(nodes: usize, pairs: &[[u32; 2]]) -> Incidence {
        // Each pair's ends in turn, grouped by node: entry `2k` is pair `k`'s first end,
        // `2k + 1` its second, so each node's entries come in the order of the pairs.
        let ends: Vec<u32> = pairs.iter().flatten().copied().collect();
        let (start, entries) = group(nodes, &ends);
        let pairs = entries
            .iter()
            .map(|&e| (e / 2) | if e % 2 == 1 { SECOND_END } else { 0 })
            .collect();
        Incidence { start, pairs }
    }
}

impl Operator<'_> {
    fn couplings(&self) -> impl Iterator<Item = ([u32; 2], Sym)> + '_ {
        let listed = (self.pairs.iter().enumerate()).map(|(k, &pair)| (pair, self.blocks.get(k)));
        listed.chain(
            self.more_pairs
                .iter()
                .copied()
                .zip(self.more_blocks.iter().copied()),
        )
    }

    /// `y = A·x`, zero at held nodes.
    pub fn apply(&self, x: &[Vec3], y: &mut [Vec3]) {
        for ((y, own), &x) in y.iter_mut().zip(self.own).zip(x) {
            *y = sym_mul(own, x);
        }
        for ([a, c], b) in self.couplings() {
            let (a, c) = (a as usize, c as usize);
            let f = sym_mul(&b, x[a] - x[c]);
            y[a] += f;
            y[c] -= f;
        }
        if let Some(free) = self.free {
            for (y, &f) in y.iter_mut().zip(free) {
                *y = *y * f;
            }
        }
    }

    /// `t = r − A·e` by its list of pairs, with `forces` room for a force per pair (a level
    /// too small for its products in stencil order to pay: see [`STENCIL_NODES`]). With more
    /// than one thread in the team, and where the level has no pairs found at the iterate, it is
    /// spread over the threads: each pair's force first, then each row gathers its pairs' in
    /// the order of the pairs, as the loop over pairs adds them (the same bits either way).
    fn list_residual(
        &self,
        incidence: &Incidence,
        r: &[Vec3],
        e: &[Vec3],
        t: &mut [Vec3],
        forces: &mut [Vec3],
    ) {
        let Some(incidence) = Some(incidence)
            .filter(|_| self.more_pairs.is_empty() && self.free.is_none() && team::threads() > 1)
        else {
            self.apply(e, t);
            for (t, &r) in t.iter_mut().zip(r) {
                *t = r - *t;
            }
            return;
        };
        let forces = &mut forces[..self.pairs.len()];
        let size = team::chunk_size(forces.len(), MIN_NODES);
        team::for_each_chunk([&mut *forces], size, &|chunk, [f]| {
            let at = chunk * size;
            for (k, (f, &[a, c])) in f.iter_mut().zip(&self.pairs[at..]).enumerate() {
                *f = sym_mul(&self.blocks.get(at + k), e[a as usize] - e[c as usize]);
            }
        });
        let forces = &*forces;
        let size = team::chunk_size(t.len(), MIN_NODES);
        team::for_each_chunk([t], size, &|chunk, [t]| {
            for (i, t) in t.iter_mut().enumerate() {
                let a = chunk * size + i;
                let mut row = sym_mul(&self.own[a], e[a]);
                let (from, to) = (incidence.start[a], incidence.start[a + 1]);
                for &k in &incidence.pairs[from as usize..to as usize] {
                    let f = forces[(k & !SECOND_END) as usize];
                    if k & SECOND_END == 0 {
                        row += f;
                    } else {
                        row -= f;
                    }
                }
                *t = r[a] - row;
            }
        });
    }

    /// `e += ω·D⁻¹·r` (zero at held nodes).
    fn jacobi(&self, r: &[Vec3], omega: f64, e: &mut [Vec3]) {
        let size = team::chunk_size(e.len(), MIN_NODES);
        team::for_each_chunk([e], size, &|chunk, [e]| {
            let at = chunk * size..chunk * size + e.len();
            let free = self.free.map(|f| &f[at.clone()]);
            jacobi_chunk(&r[at.clone()], &self.diag_inv[at], free, omega, e);
        });
    }

    /// `z = ω·D⁻¹·r + P·e` (`correction`: each node's aggregate on the next level and that
    /// level's correction `e`, or each node's own, where given; zero at held nodes); returns
    /// `r·z`, summed as
    /// [`super::cg::dot`] sums it (into `sums`). Each node's `z` is the sum
    /// [`Operator::jacobi`] then [`prolong`] make of it from zero.
    pub(super) fn jacobi_dot(
        &self,
        r: &[Vec3],
        omega: f64,
        correction: Option<Correction<&[Vec3]>>,
        z: &mut [Vec3],
        sums: &mut [f64],
    ) -> f64 {
        let size = sum_chunk(z.len());
        team::for_each_chunk_into([z], size, sums, &|chunk, [z]| {
            let at = chunk * size..chunk * size + z.len();
            let free = self.free.map(|f| &f[at.clone()]);
            let correction = correction.map(|c| c.of(at.clone()));
            let (r, diag_inv) = (&r[at.clone()], &self.diag_inv[at]);
            jacobi_dot_chunk(r, diag_inv, free, omega, correction, z)
        });
        sums.iter().sum()
    }

    /// The inverses of the diagonal blocks into `diag_inv`: `own` plus the block of every
    /// pair, in `pairs` and `more_pairs`, at both its nodes. With more than one thread in the
    /// team and `incidence` (of `pairs`), each node gathers its pairs' blocks, in the order of
    /// the pairs as the loop over them adds them, and the nodes are spread over the threads.
    pub fn invert_diagonal(
        own: &[Sym],
        (pairs, blocks): (&[[u32; 2]], &[Sym]),
        (more_pairs, more_blocks): (&[[u32; 2]], &[Sym]),
        incidence: Option<&Incidence>,
        diag_inv: &mut [Sym],
    ) {
        let incidence = incidence.filter(|i| {
            team::threads() > 1
                && i.start.len() == own.len() + 1
                && i.pairs.len() == 2 * pairs.len()
        });
        let size = team::chunk_size(own.len(), MIN_NODES);
        match incidence {
            Some(incidence) => team::for_each_chunk([&mut *diag_inv], size, &|chunk, [d]| {
                for (i, d) in d.iter_mut().enumerate() {
                    let a = chunk * size + i;
                    *d = own[a];
                    let (from, to) = (incidence.start[a], incidence.start[a + 1]);
                    for &k in &incidence.pairs[from as usize..to as usize] {
                        add_sym(d, &blocks[(k & !SECOND_END) as usize]);
                    }
                }
            }),
            None => {
                diag_inv.copy_from_slice(own);
                for (&[a, c], b) in pairs.iter().zip(blocks) {
                    add_sym(&mut diag_inv[a as usize], b);
                    add_sym(&mut diag_inv[c as usize], b);
                }
            }
        }
        Operator::add_and_invert((more_pairs, more_blocks), diag_inv);
    }

    /// `diag_inv`, the diagonal blocks summed but for the pairs `more_pairs` (found at the
    /// iterate), with those added in order, then inverted.
    pub fn add_and_invert((more_pairs, more_blocks): (&[[u32; 2]], &[Sym]), diag_inv: &mut [Sym]) {
        for (&[a, c], b) in more_pairs.iter().zip(more_blocks) {
            add_sym(&mut diag_inv[a as usize], b);
            add_sym(&mut diag_inv[c as usize], b);
        }
        let size = team::chunk_size(diag_inv.len(), MIN_NODES);
        team::for_each_chunk([diag_inv], size, &|_, [d]| {
            for d in d.iter_mut() {
                *d = sym_inverse(d);
            }
        });
    }
}

/// A coarse level: its operator, its map to the next coarser level, and its work vectors.
#[derive(Clone, Debug, Default)]
struct Level {
    own: Vec<Sym>,
    pairs: Vec<[u32; 2]>,
    blocks: Vec<Sym>,
    more_pairs: Vec<[u32; 2]>,
    more_blocks: Vec<Sym>,
    diag_inv: Vec<Sym>,
    /// Each node's aggregate and each pair's pair on the next level (empty on the coarsest).
    down: Restriction,
    incidence: Incidence,
    /// The pairs' blocks in stencil order, for the level's products; whether the level's
    /// products take them (see [`STENCIL_NODES`]), else they go by the list
    /// of pairs, with a force per pair in `forces`.
    stencil: LevelStencil,
    in_stencil_order: bool,
    forces: Vec<Vec3>,
    /// Right-hand side, correction, residual.
    r: Vec<Vec3>,
    e: Vec<Vec3>,
    t: Vec<Vec3>,
}

/// From one level to the next coarser: each node's aggregate, and the nodes and pairs that
/// sum into each aggregate and coarse pair.
#[derive(Clone, Debug, Default)]
struct Restriction {
    parent: Vec<u32>,
    /// Each aggregate's nodes, ascending: those of `J` are `nodes[start[J] .. start[J + 1]]`.
    start: Vec<u32>,
    nodes: Vec<u32>,
    /// Each coarse pair's fine pairs, ascending: those of `K` are
    /// `pairs[pair_start[K] .. pair_start[K + 1]]`.
    pair_start: Vec<u32>,
    pairs: Vec<u32>,
}

impl Restriction {
    /// The nodes of aggregate `j`.
    fn len(&self, j: usize) -> usize {
        (self.start[j + 1] - self.start[j]) as usize
    }
}

/// The coarse levels of `A`, built for a model's points and springs.
#[derive(Clone, Debug, Default)]
pub(super) struct Multigrid {
    /// The fine pairs it was built for: a model whose springs change is built for anew.
    built_for: Vec<[u32; 2]>,
    /// From the fine level to the first coarse one: the aggregation, and the transfers of the
    /// residual and the correction.
    down: Restriction,
    transfer: Transfer,
    /// The first coarse level's operator over the large full lattices.
    galerkin: Galerkin,
    /// The fine level's points.
    points: usize,
    levels: Vec<Level>,
    /// The least nodes of a level whose correction is over-corrected, where not
    /// [`OVER_CORRECTED_NODES`] (tests).
    over_corrected_from: Option<usize>,
    /// Whether the step's field swirls, and whether a solve of this step found the
    /// over-relaxed cycle not positive definite: the coarse levels' Jacobi weight is then
    /// [`OMEGA_DAMPED`], else [`OMEGA`].
    swirls: bool,
    failed_over_relaxed: bool,
    /// The over-relaxed weight, where not [`OMEGA`] (tests).
    over_relaxed: Option<f64>,
}

impl Multigrid {
    /// Levels for `model` whose fine pairs are `pairs` (the springs, flat point indices), with
    /// room for `more` pairs found at the iterate; kept when already built for the same pairs.
    pub fn build(&mut self, model: &Model, pairs: &[[u32; 2]], more: usize) {
        if self.built_for == pairs && self.points == model.point_count() {
            return;
        }
        // Each fine node's body and lattice coordinates.
        let mut nodes: Vec<Node> = Vec::with_capacity(model.point_count());
        for (b, body) in model.bodies().iter().enumerate() {
            let lattice = body.lattice();
            for q in 0..body.len() {
                let [i, j, k] = lattice.coords(q);
                nodes.push((b as u32, [i as u32, j as u32, k as u32]));
            }
        }
        let mut levels = Vec::new();
        let mut downs = Vec::new();
        let mut level_pairs = pairs.to_vec();
        while nodes.iter().any(|(_, c)| *c != [0; 3]) {
            let (down, coarse_nodes, coarse_pairs) = coarsen(&nodes, &level_pairs);
            let n = coarse_nodes.len();
            let mut stencil = LevelStencil::new(&lattices(&coarse_nodes));
            let slots: Vec<u32> = (coarse_pairs.iter())
                .map(|&[a, c]| {
                    (stencil.slot(a as usize, c as usize))
                        .expect("the aggregates a spring joins are lattice neighbours")
                })
                .collect();
            stencil.place_pairs(&slots);
            downs.push(down);
            levels.push(Level {
                own: vec![[0.0; 6]; n],
                blocks: vec![[0.0; 6]; coarse_pairs.len()],
                pairs: coarse_pairs.clone(),
                more_pairs: Vec::with_capacity(more),
                more_blocks: Vec::with_capacity(more),
                diag_inv: vec![[0.0; 6]; n],
                down: Restriction::default(),
                incidence: Incidence::of(n, &coarse_pairs),
                in_stencil_order: n >= STENCIL_NODES * stencil.lattice_count(),
                stencil,
                forces: vec![Vec3::ZERO; coarse_pairs.len()],
                r: vec![Vec3::ZERO; n],
                e: vec![Vec3::ZERO; n],
                t: vec![Vec3::ZERO; n],
            });
            nodes = coarse_nodes;
            level_pairs = coarse_pairs;
        }
        let mut downs = downs.into_iter();
        self.down = downs.next().unwrap_or_default();
        (self.transfer, self.galerkin) = match levels.first() {
            None => Default::default(),
            Some(first) => (
                Transfer::new(model, &self.down),
                Galerkin::new(model, &self.down, &first.pairs),
            ),
        };
        for (level, down) in levels.iter_mut().zip(downs) {
            level.down = down;
        }
        self.levels = levels;
        self.points = model.point_count();
        self.built_for = pairs.to_vec();
    }

    /// At each step's start: whether its field swirls (see [`OMEGA_DAMPED`]); the cycle
    /// over-relaxed again where it does not.
    pub fn start_step(&mut self, swirls: bool) {
        (self.swirls, self.failed_over_relaxed) = (swirls, false);
    }

    /// After a solve found the cycle not positive definite: its coarse levels damped for the
    /// rest of the step ([`OMEGA_DAMPED`]). True when they were over-relaxed (a solve with the
    /// damped cycle may succeed where this one failed).
    pub fn damp(&mut self) -> bool {
        let over_relaxed = !(self.swirls || self.failed_over_relaxed);
        self.failed_over_relaxed = true;
        over_relaxed
    }

    /// The coarse levels' Jacobi weight.
    pub(super) fn omega(&self) -> f64 {
        if self.swirls || self.failed_over_relaxed {
            OMEGA_DAMPED
        } else {
            self.over_relaxed.unwrap_or(OMEGA)
        }
    }

    /// Over-relaxes the coarse levels by `omega` instead of [`OMEGA`] (tests: a weight at which
    /// the cycle is not positive definite).
    #[cfg(test)]
    pub(super) fn over_relax_by(&mut self, omega: f64) {
        self.over_relaxed = Some(omega);
    }

    /// The least nodes of a level that takes the next one's correction scaled up, and the
    /// scale ([`OVER_CORRECTION`], or [`OVER_CORRECTION_TRILINEAR`] after trilinear transfers).
    fn over_correction(&self) -> (usize, f64) {
        let from = self.over_corrected_from.unwrap_or(OVER_CORRECTED_NODES);
        if self.transfer.is_trilinear() {
            (from, OVER_CORRECTION_TRILINEAR)
        } else {
            (from, OVER_CORRECTION)
        }
    }

    /// The coarse operators for the fine operator `fine` (after each assembly of `A`).
    pub fn assemble(&mut self, fine: &Operator) {
        let Some((first, _)) = self.levels.split_first_mut() else {
            return;
        };
        restrict_operator(fine, &self.down, first, Some(&mut self.galerkin));
        for l in 1..self.levels.len() {
            let (finer, coarser) = self.levels.split_at_mut(l);
            let finer = &finer[l - 1];
            restrict_operator(&finer.operator(), &finer.down, &mut coarser[0], None);
        }
    }

    /// `z ≈ A⁻¹·r` by one V-cycle from the fine operator `fine` (zero at held points), the
    /// coarse levels' products in `precision`; returns `r·z`, summed as [`super::cg::dot`] sums
    /// it (into `sums`, one per chunk of [`sum_chunk`] points).
    ///
    /// The fine level's smoothing and the coarse correction are one pass after the cycle (the
    /// smoothing needs only `r`), with `r·z` summed in it, where they took three passes over the
    /// points (`z` filled with zeros on the leader alone, the smoothing, the correction) and the
    /// conjugate gradients a fourth for `r·z`.
    pub fn precondition(
        &mut self,
        fine: &Operator,
        r: &[Vec3],
        z: &mut [Vec3],
        precision: Precision,
        sums: &mut [f64],
    ) -> f64 {
        let (over, omega) = (self.over_correction(), self.omega());
        let Some(first) = self.levels.first_mut() else {
            // One node per body already: block Jacobi is the exact solve of that level.
            return fine.jacobi_dot(r, 1.0, None, z, sums);
        };
        let transfer = &mut self.transfer;
        if transfer.is_trilinear() {
            transfer.restrict_double(&self.down, r, &mut first.r);
        } else {
            restrict(&self.down, r, &mut first.r);
        }
        cycle(&mut self.levels, precision, over, omega);
        let correction = if transfer.is_trilinear() {
            transfer.prolong(&self.down, &self.levels[0].e, Precision::Double);
            Correction::Points(&transfer.correction[..])
        } else {
            Correction::Aggregates(&self.down.parent[..], &self.levels[0].e[..])
        };
        fine.jacobi_dot(r, FINE_OMEGA, Some(correction), z, sums)
    }
}

/// [`Multigrid::precondition`] for `r` and `z` in single precision as structure of arrays,
/// the finest level's `D⁻¹` in `diag_inv` (single precision, `[xx, yy, zz, xy, xz, yz]`):
/// the single-precision conjugate gradients' preconditioner; with `coarse` (the multigrid),
/// its cycle, else `A`'s diagonal blocks alone. Returns `r·z` (in double precision), summed
/// as [`super::cg::dot`] sums it (into `sums`).
pub(super) fn precondition_single(
    coarse: Option<&mut Multigrid>,
    free: Option<&[f64]>,
    diag_inv: &[Vec<f32>; 6],
    r: [&[f32]; 3],
    z: [&mut [f32]; 3],
    precision: Precision,
    sums: &mut [f64],
) -> f64 {
    let Some(multigrid) = coarse.filter(|m| !m.levels.is_empty()) else {
        return jacobi_dot_single(free, diag_inv, r, 1.0, None, z, sums);
    };
    let (over, omega) = (multigrid.over_correction(), multigrid.omega());
    let (down, transfer) = (&multigrid.down, &mut multigrid.transfer);
    transfer.restrict(down, r, &mut multigrid.levels[0].r);
    cycle(&mut multigrid.levels, precision, over, omega);
    let correction = if transfer.is_trilinear() {
        transfer.prolong(down, &multigrid.levels[0].e, Precision::Single);
        Correction::Points(transfer.correction_single.each_ref().map(|c| &c[..]))
    } else {
        Correction::Aggregates(&down.parent[..], &multigrid.levels[0].e[..])
    };
    jacobi_dot_single(free, diag_inv, r, FINE_OMEGA, Some(correction), z, sums)
}

/// The fine level's correction as [`Operator::jacobi_dot`] and [`jacobi_dot_single`] add it:
/// each point's aggregate and the next level's correction, or each point's own (`P`: `Vec3`s,
/// or single precision as structure of arrays).
#[derive(Clone, Copy)]
pub(super) enum Correction<'a, P> {
    Aggregates(&'a [u32], &'a [Vec3]),
    Points(P),
}

impl<'a, P> Correction<'a, P> {
    /// The part for the points `at`, `part` taking the points' own.
    fn part(self, at: std::ops::Range<usize>, part: impl FnOnce(P) -> P) -> Correction<'a, P> {
        match self {
            Correction::Aggregates(parent, coarse) => Correction::Aggregates(&parent[at], coarse),
            Correction::Points(c) => Correction::Points(part(c)),
        }
    }
}

impl<'a> Correction<'a, &'a [Vec3]> {
    /// The part for the points `at`.
    fn of(self, at: std::ops::Range<usize>) -> Self {
        self.part(at.clone(), |c| &c[at])
    }
}

impl<'a> Correction<'a, [&'a [f32]; 3]> {
    /// The part for the points `at`.
    fn of(self, at: std::ops::Range<usize>) -> Self {
        self.part(at.clone(), |c| c.map(|c| &c[at.clone()]))
    }
}

/// `z = ω·D⁻¹·r + P·e` in single precision (see [`Operator::jacobi_dot`]); returns `r·z`.
fn jacobi_dot_single(
    free: Option<&[f64]>,
    diag_inv: &[Vec<f32>; 6],
    r: [&[f32]; 3],
    omega: f64,
    correction: Option<Correction<[&[f32]; 3]>>,
    z: [&mut [f32]; 3],
    sums: &mut [f64],
) -> f64 {
    let size = sum_chunk(z[0].len());
    team::for_each_chunk_into(z, size, sums, &|chunk, z| {
        let at = chunk * size..chunk * size + z[0].len();
        let free = free.map(|f| &f[at.clone()]);
        let correction = correction.map(|c| c.of(at.clone()));
        let r = r.map(|r| &r[at.clone()]);
        let diag_inv = std::array::from_fn(|c| &diag_inv[c][at.clone()]);
        jacobi_dot_single_chunk(r, diag_inv, free, omega as f32, correction, z)
    });
    sums.iter().sum()
}

crate::compute::simd::multiversion! {
    /// One chunk of [`jacobi_dot_single`], compiled per tier (the same bits on each); `r·z`
    /// summed as [`dot_single`] sums.
    fn jacobi_dot_single_chunk(
        r: [&[f32]; 3],
        diag_inv: [&[f32]; 6],
        free: Option<&[f64]>,
        omega: f32,
        correction: Option<Correction<[&[f32]; 3]>>,
        z: [&mut [f32]; 3],
    ) -> f64 {
        let [z0, z1, z2] = z;
        let n = z0.len();
        let (z1, z2) = (&mut z1[..n], &mut z2[..n]);
        let [r0, r1, r2] = r.map(|r| &r[..n]);
        let [xx, yy, zz, xy, xz, yz] = diag_inv.map(|d| &d[..n]);
        let free = free.map(|f| &f[..n]);
        for i in 0..n {
            let f = match free {
                Some(free) => free[i] as f32,
                None => 1.0,
            };
            let w = omega * f;
            z0[i] = (xx[i] * r0[i] + xy[i] * r1[i] + xz[i] * r2[i]) * w;
            z1[i] = (xy[i] * r0[i] + yy[i] * r1[i] + yz[i] * r2[i]) * w;
            z2[i] = (xz[i] * r0[i] + yz[i] * r1[i] + zz[i] * r2[i]) * w;
        }
        match correction {
            Some(Correction::Aggregates(parent, coarse)) => {
                let parent = &parent[..n];
                for i in 0..n {
                    let f = match free {
                        Some(free) => free[i] as f32,
                        None => 1.0,
                    };
                    let c = coarse[parent[i] as usize];
                    z0[i] += c.x as f32 * f;
                    z1[i] += c.y as f32 * f;
                    z2[i] += c.z as f32 * f;
                }
            }
            Some(Correction::Points(c)) => {
                let [c0, c1, c2] = c.map(|c| &c[..n]);
                for i in 0..n {
                    let f = match free {
                        Some(free) => free[i] as f32,
                        None => 1.0,
                    };
                    z0[i] += c0[i] * f;
                    z1[i] += c1[i] * f;
                    z2[i] += c2[i] * f;
                }
            }
            None => {}
        }
        dot_single([r0, r1, r2], [&*z0, &*z1, &*z2])
    }
}

crate::compute::simd::multiversion! {
    /// One chunk of [`Operator::jacobi`]: `e += ω·D⁻¹·r·f` point by point (`f` the point's
    /// `free`, 1 without), compiled per tier (the same bits on each).
    fn jacobi_chunk(r: &[Vec3], diag_inv: &[Sym], free: Option<&[f64]>, omega: f64, e: &mut [Vec3]) {
        let n = e.len();
        let (r, diag_inv) = (&r[..n], &diag_inv[..n]);
        for i in 0..n {
            let f = free.map_or(1.0, |f| f[i]);
            e[i] += sym_mul(&diag_inv[i], r[i]) * (omega * f);
        }
    }
}

crate::compute::simd::multiversion! {
    /// One chunk of [`Operator::jacobi_dot`]: `z = ω·D⁻¹·r·f + c·f` point by point (`c` the
    /// point's correction, `f` its `free`, 1 without), then `r·z` summed in order. Compiled per tier like
    /// the stencil's kernels (the same bits on each): on the baseline this loop of 3×3 blocks
    /// ran two lanes at a time at best, and took 6.7 % of a dropped 32³ cube's step.
    fn jacobi_dot_chunk(
        r: &[Vec3],
        diag_inv: &[Sym],
        free: Option<&[f64]>,
        omega: f64,
        correction: Option<Correction<&[Vec3]>>,
        z: &mut [Vec3],
    ) -> f64 {
        let n = z.len();
        let (r, diag_inv) = (&r[..n], &diag_inv[..n]);
        for i in 0..n {
            let f = free.map_or(1.0, |f| f[i]);
            let mut e = Vec3::ZERO;
            e += sym_mul(&diag_inv[i], r[i]) * (omega * f);
            match correction {
                Some(Correction::Aggregates(parent, coarse)) => {
                    e += coarse[parent[i] as usize] * f;
                }
                Some(Correction::Points(own)) => e += own[i] * f,
                None => {}
            }
            z[i] = e;
        }
        r.iter().zip(z.iter()).map(|(r, z)| r.dot(*z)).sum()
    }
}

impl Level {
    fn operator(&self) -> Operator<'_> {
        Operator {
            own: &self.own,
            pairs: &self.pairs,
            blocks: Blocks::Listed(&self.blocks),
            more_pairs: &self.more_pairs,
            more_blocks: &self.more_blocks,
            diag_inv: &self.diag_inv,
            free: None,
        }
    }
}

/// One V-cycle from `levels[0].r` into `levels[0].e`, the levels' products in `precision`,
/// smoothed by Jacobi sweeps of weight `omega`; a level of at least `over.0` nodes takes the
/// next level's correction times `over.1` (see [`Multigrid::over_correction`]).
fn cycle(levels: &mut [Level], precision: Precision, over: (usize, f64), omega: f64) {
    let Some((this, coarser)) = levels.split_first_mut() else {
        return;
    };
    // The small levels on this thread alone: on the team, their loops of a few microseconds
    // each cost more in the threads' start and wait than they saved (the 32³ cube dropped on a
    // floor, 2 threads: 50 ms in its levels of 512 nodes and fewer, 36 ms on one thread).
    if this.e.len() < SERIAL_NODES && team::threads() > 1 {
        team::serially(|| cycle(levels, precision, over, omega));
        return;
    }
    // The correction, residual and stencil leave the level while its operator is borrowed
    // (taking them out and back does not allocate).
    let (mut e, mut t) = (std::mem::take(&mut this.e), std::mem::take(&mut this.t));
    let mut stencil = std::mem::take(&mut this.stencil);
    let mut forces = std::mem::take(&mut this.forces);
    let (op, r, incidence) = (this.operator(), &this.r, &this.incidence);
    let in_stencil_order = this.in_stencil_order;
    let mut residual = |e: &[Vec3], t: &mut [Vec3]| {
        if in_stencil_order {
            level_residual(&op, &mut stencil, r, e, t, precision);
        } else {
            op.list_residual(incidence, r, e, t, &mut forces);
        }
    };
    e.fill(Vec3::ZERO);
    if let Some(next) = coarser.first_mut() {
        op.jacobi(r, omega, &mut e);
        residual(&e, &mut t);
        restrict(&this.down, &t, &mut next.r);
        cycle(coarser, precision, over, omega);
        let scale = if e.len() >= over.0 { over.1 } else { 1.0 };
        prolong(&this.down, &coarser[0].e, &mut e, scale);
        residual(&e, &mut t);
        op.jacobi(&t, omega, &mut e);
    } else {
        op.jacobi(r, 1.0, &mut e);
        for _ in 1..COARSEST_SWEEPS {
            residual(&e, &mut t);
            op.jacobi(&t, 1.0, &mut e);
        }
    }
    (this.e, this.t, this.stencil, this.forces) = (e, t, stencil, forces);
}

/// `t = r − A·e` on a coarse level whose operator is `op` and whose pairs' blocks are in
/// `stencil`, that part in `precision`.
fn level_residual(
    op: &Operator,
    stencil: &mut LevelStencil,
    r: &[Vec3],
    e: &[Vec3],
    t: &mut [Vec3],
    precision: Precision,
) {
    stencil.residual(op.own, r, e, t, precision);
    // The pairs found at the iterate (contacts between bodies), in order.
    for (&[a, c], b) in op.more_pairs.iter().zip(op.more_blocks) {
        let (a, c) = (a as usize, c as usize);
        let f = sym_mul(b, e[a] - e[c]);
        t[a] -= f;
        t[c] += f;
    }
}

/// Each body's lattice among a level's `nodes` (which hold every node of it, in flat order, one
/// body after another): its first node and its point counts.
fn lattices(nodes: &[Node]) -> Vec<(usize, [usize; 3])> {
    let mut lattices: Vec<(u32, usize, [usize; 3])> = Vec::new();
    for (i, &(body, c)) in nodes.iter().enumerate() {
        if lattices.last().is_none_or(|l| l.0 != body) {
            lattices.push((body, i, [0; 3]));
        }
        let counts = &mut lattices.last_mut().expect("pushed").2;
        for (n, &c) in counts.iter_mut().zip(&c) {
            *n = (*n).max(c as usize + 1);
        }
    }
    lattices
        .into_iter()
        .map(|(_, first, counts)| (first, counts))
        .collect()
}

/// Whether `body`'s lattice is whole and its aggregates under `down` are numbered from its first
/// point's in the order of their halved coordinates (`coarsen` numbers them in the order of their
/// first node, which for a full lattice is that order): the trilinear transfers and the stencil
/// sums of the first coarse level address them so.
fn aggregates_in_order(body: &crate::model::body::Body, down: &Restriction) -> bool {
    let points = body.points();
    let Some(first) = points.clone().next() else {
        return false;
    };
    let coarse = down.parent[first] as usize;
    let halves = body.lattice().counts.map(|n| n.div_ceil(2));
    body.lattice().len() == points.len()
        && points.clone().all(|p| {
            let [i, j, k] = body.lattice().coords(p - points.start);
            let own = (i / 2 * halves[1] + j / 2) * halves[2] + k / 2;
            down.parent[p] as usize == coarse + own
        })
}

/// `coarse[J] = Σ fine[p]` over the nodes `p` of aggregate `J`, in their order.
fn restrict(down: &Restriction, fine: &[Vec3], coarse: &mut [Vec3]) {
    let size = team::chunk_size(coarse.len(), MIN_NODES);
    team::for_each_chunk([coarse], size, &|chunk, [coarse]| {
        for (i, c) in coarse.iter_mut().enumerate() {
            let j = chunk * size + i;
            let nodes = &down.nodes[down.start[j] as usize..down.start[j + 1] as usize];
            *c = nodes
                .iter()
                .fold(Vec3::ZERO, |sum, &p| sum + fine[p as usize]);
        }
    });
}

/// `fine[p] += coarse[J]·scale` for each node `p` of each aggregate `J` (a coarse level's nodes
/// all move; the finest level's correction is [`Operator::jacobi_dot`]'s).
fn prolong(down: &Restriction, coarse: &[Vec3], fine: &mut [Vec3], scale: f64) {
    let size = team::chunk_size(fine.len(), MIN_NODES);
    team::for_each_chunk([fine], size, &|chunk, [fine]| {
        for (i, e) in fine.iter_mut().enumerate() {
            let p = chunk * size + i;
            *e += coarse[down.parent[p] as usize] * scale;
        }
    });
}

/// The Galerkin operator `PᵀAP` of `fine` into `coarse` (see the module documentation); a pair
/// with one held end adds its block to the moving end's aggregate. Each coarse block is summed
/// in the order of the fine nodes and pairs whoever computes it, so the aggregates and the
/// coarse pairs are spread over the team's threads with the same bits.
fn restrict_operator(
    fine: &Operator,
    down: &Restriction,
    coarse: &mut Level,
    galerkin: Option<&mut Galerkin>,
) {
    match fine.blocks {
        Blocks::Listed(blocks) => restrict_with(fine, down, coarse, |k| blocks[k], None),
        Blocks::Slots { slots, components } => {
            let galerkin = galerkin.filter(|g| g.is_used()).map(|g| (g, components));
            let block = |k: usize| {
                let slot = slots[k] as usize;
                std::array::from_fn(|c| f64::from(components[c][slot]))
            };
            restrict_with(fine, down, coarse, block, galerkin)
        }
    }
}

/// [`restrict_operator`] with the fine pairs' blocks from `block` (inlined for each kind of
/// [`Blocks`], so that the loop over the fine pairs does not branch on it), and the large full
/// lattices' pairs summed in stencil order by `galerkin` from the fine blocks' components where
/// given (and no point is held).
#[inline(always)]
fn restrict_with(
    fine: &Operator,
    down: &Restriction,
    coarse: &mut Level,
    block: impl Fn(usize) -> Sym + Sync,
    galerkin: Option<(&mut Galerkin, &[Vec<f32>; 6])>,
) {
    // Where no point is held (the common case) every pair is summed without looking up its
    // ends, which lie far apart in memory (this function took 8 % of a step of a 32³ cube
    // resting on a floor, on one thread; the look-ups 1.5 % of the step's instructions).
    let held = fine.free.is_some_and(|f| f.contains(&0.0));
    let moves = |p: u32| !held || fine.free.is_none_or(|f| f[p as usize] != 0.0);
    let size = team::chunk_size(coarse.own.len(), MIN_NODES);
    team::for_each_chunk([&mut coarse.own[..]], size, &|chunk, [own]| {
        for (i, own) in own.iter_mut().enumerate() {
            let j = chunk * size + i;
            *own = [0.0; 6];
            for &p in &down.nodes[down.start[j] as usize..down.start[j + 1] as usize] {
                if moves(p) {
                    add_sym(own, &fine.own[p as usize]);
                }
            }
        }
    });
    // The pairs between two aggregates, both ends moving, into their coarse pair.
    let sum_pair = |pair: usize| {
        let mut sum = [0.0; 6];
        let (from, to) = (down.pair_start[pair], down.pair_start[pair + 1]);
        for &k in &down.pairs[from as usize..to as usize] {
            if !held || fine.pairs[k as usize].iter().all(|&p| moves(p)) {
                add_sym(&mut sum, &block(k as usize));
            }
        }
        sum
    };
    match galerkin.filter(|_| !held) {
        Some((galerkin, components)) => galerkin.restrict(components, coarse, &sum_pair),
        None => {
            // Eight items a thread: the coarse pairs met first (across the aggregates' faces)
            // sum the most fine pairs, and with one item a thread the leader summed four times
            // the helper's share (32³ benchmark, 2 threads).
            let size = team::chunk_size(coarse.blocks.len(), MIN_NODES)
                .div_ceil(PAIR_ITEMS_PER_THREAD)
                .max(MIN_NODES);
            team::for_each_chunk([&mut coarse.blocks[..]], size, &|chunk, [blocks]| {
                for (i, block) in blocks.iter_mut().enumerate() {
                    *block = sum_pair(chunk * size + i);
                }
            });
        }
    }
    // The pairs with one held end (only where a point is held), then those found at the
    // iterate, in order.
    coarse.more_pairs.clear();
    coarse.more_blocks.clear();
    let mut couple = |[a, c]: [u32; 2], b: &Sym, found: bool| {
        let (pa, pc) = (down.parent[a as usize], down.parent[c as usize]);
        match (moves(a), moves(c)) {
            (true, true) if pa == pc || !found => {}
            (true, true) => {
                coarse.more_pairs.push([pa, pc]);
                coarse.more_blocks.push(*b);
            }
            (true, false) => add_sym(&mut coarse.own[pa as usize], b),
            (false, true) => add_sym(&mut coarse.own[pc as usize], b),
            (false, false) => {}
        }
    };
    if held {
        for (k, &pair) in fine.pairs.iter().enumerate() {
            couple(pair, &block(k), false);
        }
    }
    for (&pair, b) in fine.more_pairs.iter().zip(fine.more_blocks) {
        couple(pair, b, true);
    }
    Operator::invert_diagonal(
        &coarse.own,
        (&coarse.pairs, &coarse.blocks),
        (&coarse.more_pairs, &coarse.more_blocks),
        Some(&coarse.incidence),
        &mut coarse.diag_inv,
    );
    if coarse.in_stencil_order {
        coarse.stencil.set(&coarse.blocks);
    }
}

/// The indices `i` of `of` grouped by `of[i]` (`groups` of them; entries of `INSIDE` left
/// out), ascending within each: group `g` is `members[start[g] .. start[g + 1]]`.
fn group(groups: usize, of: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; groups + 1];
    for &g in of.iter().filter(|&&g| g != INSIDE) {
        start[g as usize + 1] += 1;
    }
    for g in 0..groups {
        start[g + 1] += start[g];
    }
    let mut next = start.clone();
    let mut members = vec![0; start[groups] as usize];
    for (i, &g) in of.iter().enumerate().filter(|(_, &g)| g != INSIDE) {
        members[next[g as usize] as usize] = i as u32;
        next[g as usize] += 1;
    }
    (start, members)
}

/// The aggregates of `nodes` (2×2×2 of one body's lattice: coordinates halved, numbered in order
/// of their first node) and the pairs among them (numbered in order of their first fine pair);
/// returns the restriction, the aggregates' nodes and their pairs.
///
/// Both are found in dense tables rather than maps: each body's aggregates by their place in its
/// halved lattice, and each coarse pair by its lower aggregate and the step to the other, one of
/// 27 (the aggregates a spring joins are lattice neighbours). Through hash maps, even with an
/// integer hash, this took 96 ms of a 64³ cube's setup on 2 threads (8 ms at 32³).
fn coarsen(nodes: &[Node], pairs: &[[u32; 2]]) -> (Restriction, Vec<Node>, Vec<[u32; 2]>) {
    const NONE: u32 = u32::MAX;
    // Each body's halved lattice: its extent and its first cell in `cell_index`.
    let bodies = nodes
        .iter()
        .map(|&(b, _)| b as usize + 1)
        .max()
        .unwrap_or(0);
    let mut extent = vec![[0usize; 3]; bodies];
    for &(b, c) in nodes {
        let e = &mut extent[b as usize];
        for axis in 0..3 {
            e[axis] = e[axis].max(c[axis] as usize / 2 + 1);
        }
    }
    let mut first_cell = Vec::with_capacity(bodies);
    let mut cells = 0;
    for e in &extent {
        first_cell.push(cells);
        cells += e[0] * e[1] * e[2];
    }
    let cell = |(b, c): Node| {
        let e = extent[b as usize];
        first_cell[b as usize] + (c[0] as usize * e[1] + c[1] as usize) * e[2] + c[2] as usize
    };
    let mut cell_index = vec![NONE; cells];
    let mut coarse_nodes = Vec::new();
    let parent = nodes
        .iter()
        .map(|&(b, c)| {
            let key = (b, c.map(|c| c / 2));
            let index = &mut cell_index[cell(key)];
            if *index == NONE {
                coarse_nodes.push(key);
                *index = (coarse_nodes.len() - 1) as u32;
            }
            *index
        })
        .collect::<Vec<u32>>();
    // Each coarse pair by its lower aggregate and the step from it to the higher one (checked:
    // a step out of range would alias another pair's entry).
    let step = |lo: u32, hi: u32| {
        let ((b, a), (b2, c)) = (coarse_nodes[lo as usize], coarse_nodes[hi as usize]);
        let d = |axis: usize| i64::from(c[axis]) - i64::from(a[axis]) + 1;
        assert!(
            b == b2 && (0..3).all(|axis| (0..3).contains(&d(axis))),
            "the aggregates a spring joins are neighbours in one lattice"
        );
        ((d(0) * 3 + d(1)) * 3 + d(2)) as usize
    };
    let mut pair_index = vec![NONE; 27 * coarse_nodes.len()];
    let mut coarse_pairs = Vec::new();
    let slot = pairs
        .iter()
        .map(|&[a, c]| {
            let (pa, pc) = (parent[a as usize], parent[c as usize]);
            if pa == pc {
                return INSIDE;
            }
            let key = [pa.min(pc), pa.max(pc)];
            let index = &mut pair_index[27 * key[0] as usize + step(key[0], key[1])];
            if *index == NONE {
                coarse_pairs.push(key);
                *index = (coarse_pairs.len() - 1) as u32;
            }
            *index
        })
        .collect::<Vec<u32>>();
    let (start, members) = group(coarse_nodes.len(), &parent);
    let (pair_start, pairs) = group(coarse_pairs.len(), &slot);
    let down = Restriction {
        parent,
        start,
        nodes: members,
        pair_start,
        pairs,
    };
    (down, coarse_nodes, coarse_pairs)
}

#[cfg(test)]
mod tests {
    use super::super::sym::add_outer;
    use super::super::test_models::{box_at, on_threads, two_bodies, values, with_holes};
    use super::*;
    use crate::model::ModelBuilder;

    /// A positive definite `A` on the test model: a mass on every point, a positive semi-definite
    /// block on every spring, a few contacts between the bodies, and held points.
    struct Fine {
        own: Vec<Sym>,
        pairs: Vec<[u32; 2]>,
        blocks: Vec<Sym>,
        more_pairs: Vec<[u32; 2]>,
        more_blocks: Vec<Sym>,
        diag_inv: Vec<Sym>,
        free: Vec<f64>,
    }

    impl Fine {
        fn new(model: &Model) -> Fine {
            let n = model.point_count();
            let mut next = values(3);
            let psd = |next: &mut dyn FnMut() -> f64| -> Sym {
                let mut m = [0.0; 6];
                for _ in 0..2 {
                    let u = Vec3::new(next(), next(), next());
                    add_outer(&mut m, u, 1.0 + next());
                }
                m
            };
            let mut pairs = Vec::new();
            for body in model.bodies() {
                let first = body.points().start as u32;
                body.for_each_spring(|s| pairs.push([first + s.a as u32, first + s.b as u32]));
            }
            let blocks = pairs.iter().map(|_| psd(&mut next)).collect();
            let second = model.body(1).points().start as u32;
            let more_pairs: Vec<[u32; 2]> = (0..5).map(|i| [i * 3, second + i]).collect();
            let more_blocks = more_pairs.iter().map(|_| psd(&mut next)).collect();
            let own = (0..n)
                .map(|_| {
                    let m = 0.5 + 0.5 * next();
                    [m, m, m, 0.0, 0.0, 0.0]
                })
                .collect();
            let free = (0..n)
                .map(|i| if i % 11 == 4 { 0.0 } else { 1.0 })
                .collect();
            let mut fine = Fine {
                own,
                pairs,
                blocks,
                more_pairs,
                more_blocks,
                diag_inv: vec![[0.0; 6]; n],
                free,
            };
            Operator::invert_diagonal(
                &fine.own,
                (&fine.pairs, &fine.blocks),
                (&fine.more_pairs, &fine.more_blocks),
                None,
                &mut fine.diag_inv,
            );
            fine
        }

        fn operator(&self) -> Operator<'_> {
            Operator {
                own: &self.own,
                pairs: &self.pairs,
                blocks: Blocks::Listed(&self.blocks),
                more_pairs: &self.more_pairs,
                more_blocks: &self.more_blocks,
                diag_inv: &self.diag_inv,
                free: Some(&self.free),
            }
        }
        /// The multigrid of `model` for these pairs (not yet assembled).
        fn multigrid(&self, model: &Model) -> Multigrid {
            let mut mg = Multigrid::default();
            mg.build(model, &self.pairs, 16);
            mg
        }
    }

    fn random(n: usize, seed: u64) -> Vec<Vec3> {
        let mut next = values(seed);
        (0..n).map(|_| Vec3::new(next(), next(), next())).collect()
    }

    fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
    }

    /// Three bodies: one with holes and two full boxes of odd and even sizes, large enough for
    /// trilinear transfers.
    fn three_bodies() -> Model {
        let holes = with_holes([6, 5, 7], 7, -0.6);
        let odd = box_at([9, 8, 11], Vec3::new(8.0, 0.0, 0.0));
        let even = box_at([8, 10, 8], Vec3::new(0.0, 12.0, 0.0));
        (ModelBuilder::new().bodies(vec![holes, odd, even]).build()).unwrap()
    }

    /// `v` as structure of arrays in single precision.
    fn in_single(v: &[Vec3]) -> [Vec<f32>; 3] {
        let part = |c: fn(&Vec3) -> f64| v.iter().map(|v| c(v) as f32).collect();
        [part(|v| v.x), part(|v| v.y), part(|v| v.z)]
    }

    fn bits(v: &[Vec3]) -> Vec<[u64; 3]> {
        v.iter()
            .map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect()
    }

    /// Over each full box the fine level's transfers are trilinear: a constant correction
    /// comes back constant, and the restriction is the prolongation's transpose; over the body
    /// with holes they are constant over each aggregate (the correction everywhere times
    /// `FINE_CORRECTION`). A residual in single precision restricts as its double-precision
    /// value does, and the correction in single precision is the double one rounded.
    #[test]
    fn the_fine_levels_transfers_are_trilinear_over_full_lattices() {
        let model = three_bodies();
        let fine = Fine::new(&model);
        let mut mg = fine.multigrid(&model);
        assert!(mg.transfer.is_trilinear());
        let (n, coarse) = (model.point_count(), mg.levels[0].r.len());
        let holes = model.body(0).points();
        let scale = trilinear::FINE_CORRECTION;
        let e = vec![Vec3::new(1.0, -2.0, 3.0); coarse];
        mg.transfer.prolong(&mg.down, &e, Precision::Double);
        for (p, &c) in mg.transfer.correction.iter().enumerate() {
            assert!((c - e[0] * scale).length() < 1e-14, "point {p}: {c:?}");
        }
        let e = random(coarse, 5);
        mg.transfer.prolong(&mg.down, &e, Precision::Double);
        for p in holes.clone() {
            assert_eq!(
                mg.transfer.correction[p],
                e[mg.down.parent[p] as usize] * scale
            );
        }
        // In single precision, the same rounded.
        mg.transfer.prolong(&mg.down, &e, Precision::Single);
        let rounded = in_single(&mg.transfer.correction);
        assert!(mg.transfer.correction_single == rounded);
        // `⟨s·P·e, r⟩ = ⟨e, Pᵀ·(s·r)⟩`.
        let r = random(n, 6);
        let scaled: Vec<Vec3> = r.iter().map(|&r| r * scale).collect();
        let mut restricted = vec![Vec3::ZERO; coarse];
        mg.transfer
            .restrict_double(&mg.down, &scaled, &mut restricted);
        let (pe_r, e_pr) = (dot(&mg.transfer.correction, &r), dot(&e, &restricted));
        assert!((pe_r - e_pr).abs() < 1e-12 * pe_r.abs(), "{pe_r} ≠ {e_pr}");
        let single = in_single(&r);
        let rounded: Vec<Vec3> = (0..n)
            .map(|p| {
                Vec3::new(
                    single[0][p].into(),
                    single[1][p].into(),
                    single[2][p].into(),
                )
            })
            .collect();
        let (mut from_single, mut from_double) =
            (vec![Vec3::ZERO; coarse], vec![Vec3::ZERO; coarse]);
        let single = single.each_ref().map(|s| &s[..]);
        mg.transfer.restrict(&mg.down, single, &mut from_single);
        mg.transfer
            .restrict_double(&mg.down, &rounded, &mut from_double);
        assert_eq!(bits(&from_single), bits(&from_double));
    }

    /// The transfers' passes give the same bits on any number of threads (`f32`'s `==` tells
    /// apart all but zero's signs, which no sum here makes).
    #[test]
    fn the_transfers_have_the_same_bits_on_any_number_of_threads() {
        let bodies = vec![
            box_at([16, 15, 14], Vec3::ZERO),
            with_holes([6, 5, 7], 7, -0.6),
        ];
        let model = ModelBuilder::new().bodies(bodies).build().unwrap();
        let fine = Fine::new(&model);
        let mg = fine.multigrid(&model);
        let (n, coarse) = (model.point_count(), mg.levels[0].r.len());
        let (r, e) = (random(n, 8), random(coarse, 9));
        let single = in_single(&r);
        let run = |threads| {
            on_threads(threads, || {
                let mut mg = mg.clone();
                let (mut a, mut b) = (vec![Vec3::ZERO; coarse], vec![Vec3::ZERO; coarse]);
                mg.transfer.restrict_double(&mg.down, &r, &mut a);
                mg.transfer
                    .restrict(&mg.down, single.each_ref().map(|s| &s[..]), &mut b);
                mg.transfer.prolong(&mg.down, &e, Precision::Double);
                mg.transfer.prolong(&mg.down, &e, Precision::Single);
                let single = mg.transfer.correction_single.clone();
                ([bits(&a), bits(&b), bits(&mg.transfer.correction)], single)
            })
        };
        let one = run(1);
        for threads in [2, 3] {
            assert!(run(threads) == one, "{threads} threads");
        }
    }

    /// The first coarse level's pairs over a large full lattice, summed from the fine blocks in
    /// stencil order (`galerkin`), are those the list of fine pairs sums (to rounding: in
    /// another order), beside lattices that keep the list (one with holes, one too small); with
    /// the same bits on any number of threads.
    #[test]
    fn full_lattices_sum_their_coarse_pairs_in_stencil_order() {
        let bodies = vec![
            box_at([17, 16, 19], Vec3::ZERO),
            with_holes([6, 5, 7], 7, -0.6),
            box_at([9, 8, 11], Vec3::new(30.0, 0.0, 0.0)),
        ];
        let model = ModelBuilder::new().bodies(bodies).build().unwrap();
        let mut fine = Fine::new(&model);
        fine.free.fill(1.0);
        // Each spring's block at its stencil slot in single precision, and listed as rounded.
        let n = model.point_count();
        let mut slots = Vec::new();
        for body in model.bodies() {
            let first = body.points().start;
            body.for_each_spring_entry(|s, e| slots.push((e * n + first + s.a) as u32));
        }
        let mut components: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; 16 * n]);
        for (block, &slot) in fine.blocks.iter_mut().zip(&slots) {
            for (component, b) in components.iter_mut().zip(block.iter_mut()) {
                component[slot as usize] = *b as f32;
                *b = f64::from(*b as f32);
            }
        }
        let mut listed = fine.multigrid(&model);
        listed.assemble(&fine.operator());
        let run = |threads| {
            on_threads(threads, || {
                let mut mg = fine.multigrid(&model);
                let blocks = Blocks::Slots {
                    slots: &slots,
                    components: &components,
                };
                mg.assemble(&Operator {
                    blocks,
                    ..fine.operator()
                });
                mg
            })
        };
        let mg = run(1);
        let galerkin = &mg.galerkin;
        assert_eq!(galerkin.parts.len(), 1, "the large full box");
        let gathered = |&at: &u32| at == galerkin::GATHERED;
        assert!(galerkin.places.iter().any(gathered) && !galerkin.places.iter().all(gathered));
        for (got, want) in mg.levels.iter().zip(&listed.levels) {
            let scale = want
                .blocks
                .iter()
                .flatten()
                .fold(1.0, |m: f64, b| m.max(b.abs()));
            let close = |a: &[Sym], b: &[Sym]| {
                let far = a.iter().flatten().zip(b.iter().flatten());
                far.map(|(a, b)| (a - b).abs()).fold(0.0, f64::max) <= 1e-12 * scale
            };
            assert!(close(&got.blocks, &want.blocks), "the coarse pairs' blocks");
            assert!(close(&got.own, &want.own), "the aggregates' own blocks");
        }
        let bits_of = |mg: &Multigrid| {
            let level = &mg.levels[0];
            let all = level.blocks.iter().chain(&level.diag_inv).flatten();
            all.map(|b| b.to_bits()).collect::<Vec<u64>>()
        };
        for threads in [2, 3] {
            assert!(bits_of(&run(threads)) == bits_of(&mg), "{threads} threads");
        }
    }

    /// Conjugate gradients on a lattice of springs resting on a floor (`A` of the frame-rate
    /// job at 1/60 s, in units of a point's mass: springs of 100, the floor's penalty 400) reach
    /// a millionth of their residual in fewer iterations with the trilinear transfers than
    /// with transfers constant over each aggregate.
    #[test]
    fn trilinear_transfers_save_conjugate_gradient_iterations() {
        let model = (ModelBuilder::new().bodies(vec![box_at([12, 12, 12], Vec3::ZERO)]))
            .build()
            .unwrap();
        let n = model.point_count();
        let lattice = model.body(0).lattice().clone();
        let at = |p: u32| lattice.coords(p as usize).map(|c| c as f64);
        let mut pairs = Vec::new();
        model
            .body(0)
            .for_each_spring(|s| pairs.push([s.a as u32, s.b as u32]));
        let blocks: Vec<Sym> = (pairs.iter())
            .map(|&[a, b]| {
                let ([x, y, z], [u, v, w]) = (at(a), at(b));
                let d = Vec3::new(x - u, y - v, z - w);
                let mut m = [0.0; 6];
                add_outer(&mut m, d * (1.0 / d.length()), 100.0);
                m
            })
            .collect();
        let own: Vec<Sym> = (0..n as u32)
            .map(|p| {
                let floor = if at(p)[2] == 0.0 { 400.0 } else { 0.0 };
                [1.0, 1.0, 1.0 + floor, 0.0, 0.0, 0.0]
            })
            .collect();
        let (free, mut diag_inv) = (vec![1.0; n], vec![[0.0; 6]; n]);
        let none: (&[[u32; 2]], &[Sym]) = (&[], &[]);
        Operator::invert_diagonal(&own, (&pairs, &blocks), none, None, &mut diag_inv);
        let op = Operator {
            own: &own,
            pairs: &pairs,
            blocks: Blocks::Listed(&blocks),
            more_pairs: none.0,
            more_blocks: none.1,
            diag_inv: &diag_inv,
            free: Some(&free),
        };
        let mut trilinear = Multigrid::default();
        trilinear.build(&model, &pairs, 0);
        trilinear.assemble(&op);
        assert!(trilinear.transfer.is_trilinear());
        let mut constant = trilinear.clone();
        constant.transfer = Transfer::default();
        let b = random(n, 10);
        let mut sums = vec![0.0; super::super::cg::sum_chunks(n)];
        let mut iterations = |mg: &mut Multigrid| {
            let (mut r, mut z, mut q) = (b.clone(), vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
            let mut rz = mg.precondition(&op, &r, &mut z, Precision::Double, &mut sums);
            let (first, mut p) = (rz, z.clone());
            for iteration in 1..=200 {
                op.apply(&p, &mut q);
                let alpha = rz / dot(&p, &q);
                for (r, &q) in r.iter_mut().zip(&q) {
                    *r -= q * alpha;
                }
                let next = mg.precondition(&op, &r, &mut z, Precision::Double, &mut sums);
                if next < 1e-12 * first {
                    return iteration;
                }
                let beta = next / rz;
                rz = next;
                for (p, &z) in p.iter_mut().zip(&z) {
                    *p = z + *p * beta;
                }
            }
            panic!("no convergence in 200 iterations");
        };
        let (with, without) = (iterations(&mut trilinear), iterations(&mut constant));
        assert!(
            with * 10 <= without * 8,
            "{with} iterations trilinear, {without} constant"
        );
    }

    /// Each coarse operator is `PᵀAP` of the level above, `P` constant over each aggregate
    /// (and zero at held points).
    #[test]
    fn coarse_operators_are_galerkin_products() {
        let model = two_bodies();
        let fine = Fine::new(&model);
        let mut mg = fine.multigrid(&model);
        mg.assemble(&fine.operator());
        assert!(mg.levels.len() >= 2, "{} levels", mg.levels.len());
        assert_eq!(mg.levels.last().unwrap().own.len(), 2, "one node per body");
        let check = |finer: &Operator, down: &Restriction, coarse: &Level| {
            let (nf, nc) = (down.parent.len(), coarse.own.len());
            let xc = random(nc, 5);
            let free = |p: usize| finer.free.map_or(1.0, |f| f[p]);
            let xf: Vec<Vec3> = (0..nf)
                .map(|p| xc[down.parent[p] as usize] * free(p))
                .collect();
            let mut yf = vec![Vec3::ZERO; nf];
            finer.apply(&xf, &mut yf);
            let mut want = vec![Vec3::ZERO; nc];
            restrict(down, &yf, &mut want);
            let mut got = vec![Vec3::ZERO; nc];
            coarse.operator().apply(&xc, &mut got);
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (*g - *w).max_abs() < 1e-10 * (1.0 + w.max_abs()),
                    "{g:?} ≠ {w:?}"
                );
            }
        };
        check(&fine.operator(), &mg.down, &mg.levels[0]);
        for l in 1..mg.levels.len() {
            check(
                &mg.levels[l - 1].operator(),
                &mg.levels[l - 1].down,
                &mg.levels[l],
            );
        }
    }

    /// Each coarse level's residual, its pairs' part in stencil order, is `r − A·e` with `A`
    /// summed over its list of pairs: to rounding in double precision, and to single
    /// precision's in single.
    #[test]
    fn coarse_products_in_stencil_order_are_the_levels_own() {
        let model = two_bodies();
        let fine = Fine::new(&model);
        let mut mg = fine.multigrid(&model);
        mg.assemble(&fine.operator());
        assert!(
            !mg.levels[0].more_pairs.is_empty(),
            "contacts on the first coarse level"
        );
        for level in &mut mg.levels {
            // Whether or not the level's own products take them (its lattices are small).
            level.stencil.set(&level.blocks);
            let n = level.own.len();
            let (r, e) = (random(n, 31), random(n, 32));
            let mut want = vec![Vec3::ZERO; n];
            level.operator().apply(&e, &mut want);
            for (w, &r) in want.iter_mut().zip(&r) {
                *w = r - *w;
            }
            let scale = want.iter().map(|w| w.max_abs()).fold(1.0, f64::max);
            for (precision, tolerance) in [(Precision::Double, 1e-13), (Precision::Single, 1e-5)] {
                let mut stencil = std::mem::take(&mut level.stencil);
                let mut got = vec![Vec3::ZERO; n];
                level_residual(&level.operator(), &mut stencil, &r, &e, &mut got, precision);
                level.stencil = stencil;
                for (g, w) in got.iter().zip(&want) {
                    assert!(
                        (*g - *w).max_abs() <= tolerance * scale,
                        "{precision:?}: {g:?} ≠ {w:?}"
                    );
                }
            }
        }
    }

    /// The preconditioner is symmetric and positive definite, as conjugate gradients need: to
    /// rounding with its coarse products in double precision, and to single precision's in
    /// single.
    #[test]
    fn the_preconditioner_is_symmetric_and_positive() {
        // With constant transfers alone, and with trilinear ones (the third body's) beside them.
        symmetric_and_positive(&two_bodies());
        symmetric_and_positive(&three_bodies());
    }

    /// A cycle found not positive definite is damped for the rest of the step; where a field
    /// swirls it is damped already, and `damp` says a retry gains nothing.
    #[test]
    fn a_failed_over_relaxed_cycle_is_damped_for_the_rest_of_the_step() {
        let model = two_bodies();
        let fine = Fine::new(&model);
        let mut mg = fine.multigrid(&model);
        assert_eq!(mg.omega(), OMEGA);
        mg.start_step(true);
        assert_eq!(mg.omega(), OMEGA_DAMPED);
        assert!(!mg.damp(), "damped already where a field swirls");
        mg.start_step(false);
        assert_eq!(mg.omega(), OMEGA);
        assert!(mg.damp(), "over-relaxed before");
        assert_eq!(mg.omega(), OMEGA_DAMPED);
        assert!(!mg.damp(), "damped already");
        mg.start_step(false);
        assert_eq!(mg.omega(), OMEGA, "over-relaxed again at the next step");
    }

    /// [`the_preconditioner_is_symmetric_and_positive`] on `model`.
    fn symmetric_and_positive(model: &Model) {
        let fine = Fine::new(model);
        let n = model.point_count();
        let mut mg = fine.multigrid(model);
        mg.assemble(&fine.operator());
        let mask = |v: Vec<Vec3>| -> Vec<Vec3> {
            v.iter().zip(&fine.free).map(|(&v, &f)| v * f).collect()
        };
        let (a, b) = (mask(random(n, 21)), mask(random(n, 22)));
        // As built, with every coarse level's correction over-corrected (this model's levels
        // are below `OVER_CORRECTED_NODES`; it changes the answer), and with the smoother's
        // weight where a field swirls.
        let mut over = mg.clone();
        over.over_corrected_from = Some(0);
        let mut swirling = mg.clone();
        swirling.start_step(true);
        let (mut v, mut w, mut u) = (
            vec![Vec3::ZERO; n],
            vec![Vec3::ZERO; n],
            vec![Vec3::ZERO; n],
        );
        let mut sums = vec![0.0; super::super::cg::sum_chunks(n)];
        let av = mg.precondition(&fine.operator(), &a, &mut v, Precision::Double, &mut sums);
        over.precondition(&fine.operator(), &a, &mut w, Precision::Double, &mut sums);
        assert_ne!(v, w, "over-corrected, another preconditioner");
        swirling.precondition(&fine.operator(), &a, &mut u, Precision::Double, &mut sums);
        assert_ne!(v, u, "another weight, another preconditioner");
        // It returns `r·z` with the bits of the conjugate gradients' dot product.
        let summed = super::super::cg::dot(&a, &v, &mut sums);
        assert_eq!(av.to_bits(), summed.to_bits());
        for mg in [&mut mg, &mut over, &mut swirling] {
            for (precision, tolerance) in [(Precision::Double, 1e-12), (Precision::Single, 1e-5)] {
                let (mut za, mut zb) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
                mg.precondition(&fine.operator(), &a, &mut za, precision, &mut sums);
                mg.precondition(&fine.operator(), &b, &mut zb, precision, &mut sums);
                let (ab, ba) = (dot(&a, &zb), dot(&b, &za));
                assert!(
                    (ab - ba).abs() < tolerance * ab.abs().max(1.0),
                    "{precision:?}: {ab} ≠ {ba}"
                );
                assert!(dot(&a, &za) > 0.0 && dot(&b, &zb) > 0.0);
                for (p, &f) in fine.free.iter().enumerate() {
                    if f == 0.0 {
                        assert_eq!(za[p], Vec3::ZERO, "held point {p}");
                    }
                }
            }
        }
    }
}
