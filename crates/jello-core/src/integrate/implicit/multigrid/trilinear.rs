//! The transfers between the fine level and the first coarse one: trilinear over each body
//! whose lattice is full, has no pins and [`TRILINEAR_POINTS`] or more along each axis,
//! constant over the aggregates of the others.
//!
//! The coarse levels' operators are the Galerkin products of the aggregation (see the parent
//! module); the fine level's correction need not come through the same `P`. Taken constant
//! over each aggregate it jumps at the aggregates' faces, and the fine level's Jacobi, added
//! to it rather than smoothing after it, cannot take those jumps out again: conjugate
//! gradients then spend iterations on them. Taken trilinear instead (cell-centred: a fine node
//! weighs its own aggregate 3/4 and the next one towards it 1/4 along each axis, all on its
//! own past the lattice's end), with the restriction its transpose, the preconditioner stays
//! symmetric and positive, and the correction is smooth, while the coarse operators stay as
//! they are (the trilinear Galerkin operator has 74 blocks a row where the aggregation's has
//! 13). Conjugate-gradient iterations a step, BackwardEuler at 1/60 s over the frame-rate job
//! (2 threads, Intel Xeon with AVX-512), with [`FINE_CORRECTION`] and the parent's
//! over-correction after trilinear transfers: a cube resting on a floor at 8³, 16³, 32³ 3.9 →
//! 3.0, 5.3 → 4.4, 11.5 → 10.1; dropped on it 5.5 → 4.0, 7.6 → 6.1, 17.7 → 13.8.
//!
//! Both run as three passes along the axes, one output line of a pass at a time, each spread
//! over the team: each output is the sum of at most four inputs (two going up), in one order
//! whoever computes it.

use std::ops::Range;

use super::{aggregates_in_order, Precision, Restriction, MIN_NODES};
use crate::compute::team;
use crate::model::Model;
use crate::vec3::Vec3;

/// The scale of the fine level's correction after trilinear transfers (the over-correction of
/// the parent module, on this level). Conjugate-gradient iterations a step as in the module's
/// documentation, 1.0 → 1.2 → 1.4: at 8³ resting 3.3 → 3.1 → 3.0 and dropped 4.3 → 4.1 → 4.0,
/// at 16³ 4.8 → 4.6 → 4.4 and 6.2 → 6.5 → 6.1, at 32³ 10.1 → 9.9 → 10.1 and 14.3 → 14.1 → 13.8.
pub(super) const FINE_CORRECTION: f64 = 1.4;

/// The fewest points along each axis of a lattice whose transfers are trilinear. Smaller
/// lattices (two or three aggregates an axis) keep the constant ones: with trilinear transfers
/// on every lattice, the examples' piles and stacks of 5³ cubes (`stack.toml`, `tower.toml`
/// under BackwardEuler at their own steps) took 7–11 % more conjugate-gradient iterations and
/// 15–18 % more time.
const TRILINEAR_POINTS: usize = 8;

/// The weights along one axis of a lattice: each aggregate's fine nodes (four, the missing
/// ones weighing zero) and each fine node's aggregates (two, likewise), from [`up_taps`].
#[derive(Clone, Debug, PartialEq)]
struct Taps {
    down: Vec<[(u32, f64); 4]>,
    up: Vec<[(u32, f64); 2]>,
}

impl Taps {
    fn new(n: usize) -> Taps {
        let up = (0..n)
            .map(|i| {
                let mut taps = [(0, 0.0); 2];
                for (t, (c, w)) in taps.iter_mut().zip(up_taps(i, n)) {
                    *t = (c as u32, w);
                }
                taps
            })
            .collect();
        let down = (0..n.div_ceil(2))
            .map(|c| {
                let mut taps = [(2 * c as u32, 0.0); 4];
                for (t, (i, w)) in taps.iter_mut().zip(down_taps(c, n)) {
                    *t = (i as u32, w);
                }
                taps
            })
            .collect();
        Taps { down, up }
    }
}

/// How one body's nodes pass to the first coarse level and back.
#[derive(Clone, Debug, PartialEq)]
enum Part {
    /// A full lattice of `counts` points from fine node `fine`, its aggregates from coarse
    /// node `coarse` in the same order: trilinear.
    Trilinear {
        fine: usize,
        counts: [usize; 3],
        coarse: usize,
        taps: [Taps; 3],
    },
    /// The fine nodes `fine` (of one or more bodies in a row), whose aggregates are `coarse`:
    /// constant over each aggregate.
    Constant {
        fine: Range<usize>,
        coarse: Range<usize>,
    },
}

/// The transfers of one multigrid (see the module documentation).
#[derive(Clone, Debug, Default)]
pub(super) struct Transfer {
    parts: Vec<Part>,
    /// A double-precision residual as structure of arrays, and the passes' outputs between the
    /// axes.
    input: [Vec<f64>; 3],
    halved: [Vec<f64>; 3],
    quartered: [Vec<f64>; 3],
    /// The correction at each fine node (where a part is trilinear), and in single precision
    /// as structure of arrays.
    pub(super) correction: Vec<Vec3>,
    pub(super) correction_single: [Vec<f32>; 3],
}

/// The numbers of a residual the transfer restricts: `f32` or `f64`.
pub(super) trait Input: Copy + Into<f64> + Send + Sync {
    /// `out = Σ w[t]·x[t]` element by element.
    fn four_taps(out: &mut [f64], x: [&[Self]; 4], w: [f64; 4]);
}

impl Input for f32 {
    fn four_taps(out: &mut [f64], x: [&[f32]; 4], w: [f64; 4]) {
        four_taps_single(out, x, w);
    }
}

impl Input for f64 {
    fn four_taps(out: &mut [f64], x: [&[f64]; 4], w: [f64; 4]) {
        four_taps_double(out, x, w);
    }
}

impl Transfer {
    /// The transfers of `model`'s bodies, whose first aggregation is `down` (every fine node
    /// a point of the model, in order).
    pub(super) fn new(model: &Model, down: &Restriction) -> Transfer {
        let mut parts = Vec::with_capacity(model.bodies().len());
        let (mut halved, mut quartered) = (0, 0);
        for body in model.bodies() {
            let points = body.points();
            let counts = body.lattice().counts;
            let coarse = points.clone().next().map_or(0, |p| down.parent[p] as usize);
            let halves = counts.map(|n| n.div_ceil(2));
            let pinned = model.pins.iter().any(|&p| points.contains(&(p as usize)));
            let in_order = aggregates_in_order(body, down);
            let large = counts.iter().all(|&n| n >= TRILINEAR_POINTS);
            if large && body.is_full() && !pinned && in_order {
                halved = halved.max(halves[0] * counts[1] * counts[2]);
                quartered = quartered.max(halves[0] * halves[1] * counts[2]);
                parts.push(Part::Trilinear {
                    fine: points.start,
                    counts,
                    coarse,
                    taps: counts.map(Taps::new),
                });
            } else {
                let end = points.clone().map(|p| down.parent[p] as usize + 1).max();
                let end = end.unwrap_or(coarse);
                // Bodies in a row share one loop (a pile of small ones, one loop per body,
                // would run each on one thread).
                match parts.last_mut() {
                    Some(Part::Constant { fine, coarse: last }) => {
                        (fine.end, last.end) = (points.end, end.max(last.end));
                    }
                    _ => parts.push(Part::Constant {
                        fine: points,
                        coarse: coarse..end,
                    }),
                }
            }
        }
        let trilinear = parts.iter().any(|p| matches!(p, Part::Trilinear { .. }));
        let n = if trilinear { model.point_count() } else { 0 };
        Transfer {
            parts,
            input: std::array::from_fn(|_| vec![0.0; n]),
            halved: std::array::from_fn(|_| vec![0.0; halved]),
            quartered: std::array::from_fn(|_| vec![0.0; quartered]),
            correction: Vec3::zeros(n),
            correction_single: std::array::from_fn(|_| vec![0.0; n]),
        }
    }

    /// Whether some body's transfer is trilinear (else the aggregation's own serves).
    pub(super) fn is_trilinear(&self) -> bool {
        !self.correction.is_empty()
    }

    /// `coarse = Pᵀ·fine` for a residual in double precision.
    pub(super) fn restrict_double(
        &mut self,
        down: &Restriction,
        fine: &[Vec3],
        coarse: &mut [Vec3],
    ) {
        let mut input = std::mem::take(&mut self.input);
        let size = team::chunk_size(fine.len(), MIN_NODES);
        team::for_each_chunk(
            input.each_mut().map(|c| &mut c[..]),
            size,
            &|c, [x, y, z]| {
                for (i, f) in fine[c * size..].iter().take(x.len()).enumerate() {
                    (x[i], y[i], z[i]) = (f.x, f.y, f.z);
                }
            },
        );
        self.restrict(down, input.each_ref().map(|c| &c[..]), coarse);
        self.input = input;
    }

    /// `coarse = Pᵀ·fine` (`fine` as structure of arrays).
    pub(super) fn restrict<T: Input>(
        &mut self,
        down: &Restriction,
        fine: [&[T]; 3],
        coarse: &mut [Vec3],
    ) {
        for part in &self.parts {
            match *part {
                Part::Trilinear {
                    fine: first,
                    counts: [nx, ny, nz],
                    coarse: to,
                    taps: [ref tx, ref ty, ref tz],
                } => {
                    let [gx, gy, gz] = [nx, ny, nz].map(|n| n.div_ceil(2));
                    // Along x: planes of ny·nz.
                    let plane = ny * nz;
                    let halved = self.halved.each_mut().map(|h| &mut h[..gx * plane]);
                    lines(halved, plane, &|x, out| {
                        let (taps, w) = (
                            tx.down[x].map(|t| first + t.0 as usize * plane),
                            tx.down[x].map(|t| t.1),
                        );
                        for (o, f) in out.into_iter().zip(fine) {
                            T::four_taps(o, taps.map(|at| &f[at..at + plane]), w);
                        }
                    });
                    // Along y: rows of nz.
                    let halved = self.halved.each_ref().map(|h| &h[..gx * plane]);
                    let quartered = self.quartered.each_mut().map(|q| &mut q[..gx * gy * nz]);
                    lines(quartered, nz, &|xy, out| {
                        let (x, y) = (xy / gy, xy % gy);
                        let taps = ty.down[y].map(|t| (x * ny + t.0 as usize) * nz);
                        let w = ty.down[y].map(|t| t.1);
                        for (o, h) in out.into_iter().zip(halved) {
                            f64::four_taps(o, taps.map(|at| &h[at..at + nz]), w);
                        }
                    });
                    // Along z: each aggregate of its row.
                    let quartered = self.quartered.each_ref().map(|q| &q[..gx * gy * nz]);
                    let out = &mut coarse[to..to + gx * gy * gz];
                    let size = team::chunk_size(gx * gy, MIN_NODES.div_ceil(gz)) * gz;
                    team::for_each_chunk([out], size, &|c, [out]| {
                        for (l, out) in out.chunks_exact_mut(gz).enumerate() {
                            let at = (c * size / gz + l) * nz;
                            let [qx, qy, qz] = quartered.map(|q| &q[at..at + nz]);
                            for (o, taps) in out.iter_mut().zip(&tz.down) {
                                *o = taps.iter().fold(Vec3::ZERO, |s, &(k, w)| {
                                    let k = k as usize;
                                    s + Vec3::new(qx[k], qy[k], qz[k]) * w
                                });
                            }
                        }
                    });
                }
                Part::Constant {
                    coarse: ref aggregates,
                    ..
                } => {
                    let size = team::chunk_size(aggregates.len(), MIN_NODES);
                    let start = aggregates.start;
                    team::for_each_chunk([&mut coarse[aggregates.clone()]], size, &|c, [out]| {
                        for (i, o) in out.iter_mut().enumerate() {
                            let j = start + c * size + i;
                            let nodes = &down.nodes[down.start[j] as usize..][..down.len(j)];
                            *o = nodes.iter().fold(Vec3::ZERO, |s, &p| {
                                let p = p as usize;
                                s + Vec3::new(
                                    fine[0][p].into(),
                                    fine[1][p].into(),
                                    fine[2][p].into(),
                                )
                            });
                        }
                    });
                }
            }
        }
    }

    /// `correction = P·coarse` times [`FINE_CORRECTION`] (on every part, the constant ones
    /// too: the preconditioner stays symmetric only with one scale for all its points), into
    /// `correction` or, in single precision, `correction_single`.
    pub(super) fn prolong(&mut self, down: &Restriction, coarse: &[Vec3], into: Precision) {
        for part in &self.parts {
            match *part {
                Part::Trilinear {
                    fine: first,
                    counts: [nx, ny, nz],
                    coarse: from,
                    taps: [ref tx, ref ty, ref tz],
                } => {
                    let [gx, gy, gz] = [nx, ny, nz].map(|n| n.div_ceil(2));
                    // Along z: each fine node of each row of aggregates.
                    let rows = &coarse[from..from + gx * gy * gz];
                    let quartered = self.quartered.each_mut().map(|q| &mut q[..gx * gy * nz]);
                    lines(quartered, nz, &|xy, [ox, oy, oz]| {
                        let row = &rows[xy * gz..][..gz];
                        for (k, taps) in tz.up.iter().enumerate() {
                            let v = taps
                                .iter()
                                .fold(Vec3::ZERO, |s, &(c, w)| s + row[c as usize] * w);
                            (ox[k], oy[k], oz[k]) = (v.x, v.y, v.z);
                        }
                    });
                    // Along y: rows of nz.
                    let quartered = self.quartered.each_ref().map(|q| &q[..gx * gy * nz]);
                    let halved = self.halved.each_mut().map(|h| &mut h[..gx * ny * nz]);
                    lines(halved, nz, &|xy, out| {
                        let (x, y) = (xy / ny, xy % ny);
                        let taps = ty.up[y].map(|t| (x * gy + t.0 as usize) * nz);
                        let w = ty.up[y].map(|t| t.1);
                        for (o, q) in out.into_iter().zip(quartered) {
                            two_taps(o, taps.map(|at| &q[at..at + nz]), w);
                        }
                    });
                    // Along x: planes of ny·nz, scaled, into the correction.
                    let plane = ny * nz;
                    let halved = self.halved.each_ref().map(|h| &h[..gx * plane]);
                    let size = team::chunk_size(nx, MIN_NODES.div_ceil(plane)) * plane;
                    let taps = |line: usize| {
                        let [(a, wa), (b, wb)] = tx.up[line];
                        let [a, b] =
                            [a, b].map(|i| halved.map(|h| &h[i as usize * plane..][..plane]));
                        (a, b, [wa, wb].map(|w| w * FINE_CORRECTION))
                    };
                    let points = first..first + nx * plane;
                    match into {
                        Precision::Double => {
                            let out = &mut self.correction[points];
                            team::for_each_chunk([out], size, &|c, [out]| {
                                for (l, out) in out.chunks_exact_mut(plane).enumerate() {
                                    let (a, b, w) = taps(c * size / plane + l);
                                    two_planes(out, a, b, w);
                                }
                            });
                        }
                        Precision::Single => {
                            let out = self.correction_single.each_mut();
                            let out = out.map(|o| &mut o[points.clone()]);
                            team::for_each_chunk(out, size, &|c, out| {
                                let [x, y, z] = out.map(|o| o.chunks_exact_mut(plane));
                                for (l, ((x, y), z)) in x.zip(y).zip(z).enumerate() {
                                    let (a, b, w) = taps(c * size / plane + l);
                                    two_planes_single([x, y, z], a, b, w);
                                }
                            });
                        }
                    }
                }
                Part::Constant { ref fine, .. } => {
                    let size = team::chunk_size(fine.len(), MIN_NODES);
                    let start = fine.start;
                    let at = |p: usize| coarse[down.parent[start + p] as usize] * FINE_CORRECTION;
                    match into {
                        Precision::Double => {
                            let out = &mut self.correction[fine.clone()];
                            team::for_each_chunk([out], size, &|c, [out]| {
                                for (i, o) in out.iter_mut().enumerate() {
                                    *o = at(c * size + i);
                                }
                            });
                        }
                        Precision::Single => {
                            let out = self.correction_single.each_mut();
                            let out = out.map(|o| &mut o[fine.clone()]);
                            team::for_each_chunk(out, size, &|c, [x, y, z]| {
                                for i in 0..x.len() {
                                    let v = at(c * size + i);
                                    (x[i], y[i], z[i]) = (v.x as f32, v.y as f32, v.z as f32);
                                }
                            });
                        }
                    }
                }
            }
        }
    }
}

/// `body(line, out)` for each line of `len` outputs of `out` (structure of arrays, each output
/// written by `body`); the lines spread over the team.
fn lines(out: [&mut [f64]; 3], len: usize, body: &(dyn Fn(usize, [&mut [f64]; 3]) + Sync)) {
    let count = out[0].len() / len;
    let per_chunk = team::chunk_size(count, MIN_NODES.div_ceil(len));
    team::for_each_chunk(out, per_chunk * len, &|c, out| {
        let [x, y, z] = out.map(|o| o.chunks_exact_mut(len));
        for (l, ((x, y), z)) in x.zip(y).zip(z).enumerate() {
            body(c * per_chunk + l, [x, y, z]);
        }
    });
}

crate::compute::simd::multiversion! {
    /// `out = Σ w[t]·x[t]` element by element, `x` in single precision.
    fn four_taps_single(out: &mut [f64], x: [&[f32]; 4], w: [f64; 4]) {
        let n = out.len();
        let [x0, x1, x2, x3] = x.map(|x| &x[..n]);
        for i in 0..n {
            out[i] = f64::from(x0[i]) * w[0]
                + f64::from(x1[i]) * w[1]
                + f64::from(x2[i]) * w[2]
                + f64::from(x3[i]) * w[3];
        }
    }
}

crate::compute::simd::multiversion! {
    /// `out = Σ w[t]·x[t]` element by element.
    fn four_taps_double(out: &mut [f64], x: [&[f64]; 4], w: [f64; 4]) {
        let n = out.len();
        let [x0, x1, x2, x3] = x.map(|x| &x[..n]);
        for i in 0..n {
            out[i] = x0[i] * w[0] + x1[i] * w[1] + x2[i] * w[2] + x3[i] * w[3];
        }
    }
}

crate::compute::simd::multiversion! {
    /// `out = w[0]·x[0] + w[1]·x[1]` element by element.
    fn two_taps(out: &mut [f64], x: [&[f64]; 2], w: [f64; 2]) {
        let n = out.len();
        let [x0, x1] = x.map(|x| &x[..n]);
        for i in 0..n {
            out[i] = x0[i] * w[0] + x1[i] * w[1];
        }
    }
}

crate::compute::simd::multiversion! {
    /// `out = w[0]·a + w[1]·b` element by element (structure of arrays), rounded to single
    /// precision.
    fn two_planes_single(out: [&mut [f32]; 3], a: [&[f64]; 3], b: [&[f64]; 3], w: [f64; 2]) {
        for ((out, a), b) in out.into_iter().zip(a).zip(b) {
            let n = out.len();
            let (a, b) = (&a[..n], &b[..n]);
            for i in 0..n {
                out[i] = (a[i] * w[0] + b[i] * w[1]) as f32;
            }
        }
    }
}

crate::compute::simd::multiversion! {
    /// `out = wa·a + wb·b` element by element (`a`, `b` structure of arrays).
    fn two_planes(out: &mut [Vec3], a: [&[f64]; 3], b: [&[f64]; 3], w: [f64; 2]) {
        let n = out.len();
        let [ax, ay, az] = a.map(|a| &a[..n]);
        let [bx, by, bz] = b.map(|b| &b[..n]);
        for i in 0..n {
            out[i] = Vec3::new(
                ax[i] * w[0] + bx[i] * w[1],
                ay[i] * w[0] + by[i] * w[1],
                az[i] * w[0] + bz[i] * w[1],
            );
        }
    }
}

/// Fine node `i` of `n` along an axis: its aggregate and the next one towards it, with their
/// weights (3/4, 1/4), or its own alone (1) where that one is past the end.
fn up_taps(i: usize, n: usize) -> impl Iterator<Item = (usize, f64)> {
    let own = i / 2;
    let next = if i % 2 == 0 {
        own.checked_sub(1)
    } else {
        Some(own + 1).filter(|&c| c < n.div_ceil(2))
    };
    let own_weight = if next.is_some() { 0.75 } else { 1.0 };
    std::iter::once((own, own_weight)).chain(next.map(|c| (c, 0.25)))
}

/// Aggregate `c` along an axis of `n` fine nodes: the fine nodes that weigh it
/// ([`up_taps`]), ascending, with their weights.
fn down_taps(c: usize, n: usize) -> impl Iterator<Item = (usize, f64)> {
    ((2 * c).saturating_sub(1)..(2 * c + 3).min(n))
        .filter_map(move |i| up_taps(i, n).find(|&(to, _)| to == c).map(|(_, w)| (i, w)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Along an axis of any length, each fine node's weights sum to one over aggregates that
    /// exist, its own first; each aggregate's fine nodes are those whose weights name it, with
    /// those weights (so the restriction is the prolongation's transpose).
    #[test]
    fn the_weights_are_a_partition_of_unity_and_the_restriction_takes_their_transpose() {
        for n in 1..=9usize {
            let halves = n.div_ceil(2);
            for i in 0..n {
                let taps: Vec<_> = up_taps(i, n).collect();
                assert_eq!(
                    taps.iter().map(|t| t.1).sum::<f64>(),
                    1.0,
                    "n {n}, node {i}"
                );
                assert!(taps
                    .iter()
                    .all(|&(c, _)| c < halves && c.abs_diff(i / 2) <= 1));
                assert_eq!(taps[0].0, i / 2);
            }
            for c in 0..halves {
                let expected: Vec<(usize, f64)> = (0..n)
                    .flat_map(|i| up_taps(i, n).filter(|t| t.0 == c).map(move |t| (i, t.1)))
                    .collect();
                let taps: Vec<_> = down_taps(c, n).collect();
                assert_eq!(taps, expected, "n {n}, aggregate {c}");
                // The padded table holds the same taps, the rest weighing nothing.
                let table = Taps::new(n).down[c];
                let real: Vec<(usize, f64)> = (table.iter())
                    .filter(|t| t.1 != 0.0)
                    .map(|&(i, w)| (i as usize, w))
                    .collect();
                assert_eq!(real, expected);
                assert!(table.iter().all(|t| (t.0 as usize) < n));
            }
        }
        // Cell-centred: a node weighs its aggregate 3/4 and the next one towards it 1/4; the
        // lattice's end nodes their own alone.
        let taps = |i, n| up_taps(i, n).collect::<Vec<_>>();
        assert_eq!(taps(2, 8), [(1, 0.75), (0, 0.25)]);
        assert_eq!(taps(3, 8), [(1, 0.75), (2, 0.25)]);
        assert_eq!(taps(0, 8), [(0, 1.0)]);
        assert_eq!(taps(7, 8), [(3, 1.0)]);
        assert_eq!(taps(6, 7), [(3, 0.75), (2, 0.25)]);
    }
}
