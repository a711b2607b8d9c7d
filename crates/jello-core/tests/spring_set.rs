//! The spring set by brute force over all pairs of points, and the forces it gives.
//!
//! Independent of the stencil tables (the lattice's and the force kernel's): every unordered pair
//! of points is classified from its index offsets by docs/spec.md's words alone (axis neighbours at
//! index distance 1: structural; face and body diagonals: shear; axis neighbours at distance 2:
//! bend; nothing else), with its rest length from the rest grid. For the classic 8³ cube that is
//! 1344 structural, 3724 shear and 1152 bend springs, of rest lengths 1/7, √2/7 or √3/7, and 2/7.
//! The set must equal `Lattice::springs` and `Model::springs` as sets; and the forces of the
//! brute-force set, summed here by docs/spec.md's law, must equal `accelerations` (the stencil kernel).

mod common;

use std::collections::BTreeMap;

use common::Lcg;
use jello_core::forces::accelerations;
use jello_core::{Body, Control, Lattice, Material, ModelBuilder, SpringKind, Springs, Vec3};

/// A spring as `(a, b)` with `a < b` → (kind, rest length).
type SpringSet = BTreeMap<(usize, usize), (SpringKind, f64)>;

/// docs/spec.md's classification of the pair of points at lattice coordinates `pa` and `pb`, with the
/// rest length from the rest grid of spacings `h`; `None` when they are joined by no spring.
fn classify(pa: [usize; 3], pb: [usize; 3], h: [f64; 3]) -> Option<(SpringKind, f64)> {
    let d = [0, 1, 2].map(|c| pa[c].abs_diff(pb[c]));
    let mut sorted = d;
    sorted.sort();
    let kind = match sorted {
        // An axis neighbour at index distance 1.
        [0, 0, 1] => SpringKind::Structural,
        // A face diagonal or a body diagonal.
        [0, 1, 1] | [1, 1, 1] => SpringKind::Shear,
        // An axis neighbour at index distance 2.
        [0, 0, 2] => SpringKind::Bend,
        _ => return None,
    };
    let rest = (0..3)
        .map(|c| (d[c] as f64 * h[c]).powi(2))
        .sum::<f64>()
        .sqrt();
    Some((kind, rest))
}

/// Rest-grid spacing along each axis of a lattice of `counts` points and side lengths `size`.
fn spacing(counts: [usize; 3], size: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| size[a] / (counts[a].max(2) - 1) as f64)
}

/// Every pair of an `nx × ny × nz` lattice of side lengths `size`, classified by docs/spec.md.
fn brute_force(counts: [usize; 3], size: [f64; 3]) -> SpringSet {
    let [nx, ny, nz] = counts;
    let n = nx * ny * nz;
    // Flat index (i*ny + j)*nz + k, k fastest (docs/spec.md).
    let ijk = |p: usize| [p / (ny * nz), (p / nz) % ny, p % nz];
    let h = spacing(counts, size);
    let mut set = SpringSet::new();
    for a in 0..n {
        for b in a + 1..n {
            if let Some(spring) = classify(ijk(a), ijk(b), h) {
                set.insert((a, b), spring);
            }
        }
    }
    set
}

/// The code's springs as a set, each pair ordered `a < b`; no pair twice.
/// The springs of a box body on `lattice`.
fn box_springs(lattice: &Lattice) -> Springs {
    Body::lattice_box(lattice.clone(), Material::classic()).springs()
}

fn as_set(s: &Springs) -> SpringSet {
    let mut set = SpringSet::new();
    for n in 0..s.len() {
        let (a, b) = (s.a[n] as usize, s.b[n] as usize);
        let key = (a.min(b), a.max(b));
        assert!(
            set.insert(key, (s.kind[n], s.rest_len[n])).is_none(),
            "spring {key:?} listed twice"
        );
    }
    set
}

/// Same pairs, same kinds, rest lengths equal to 1e-15 relative (the code may compute √(2h²)
/// where this file computes √(h² + h²): a rounding apart; a wrong length is off by far more).
fn assert_same(got: &SpringSet, want: &SpringSet, what: &str) {
    let missing: Vec<_> = want.keys().filter(|k| !got.contains_key(k)).collect();
    let extra: Vec<_> = got.keys().filter(|k| !want.contains_key(k)).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "{what}: missing {} springs (first {:?}), {} extra (first {:?})",
        missing.len(),
        missing.first(),
        extra.len(),
        extra.first()
    );
    for (key, (kind, rest)) in want {
        let (k, r) = got[key];
        assert_eq!(k, *kind, "{what}: kind of {key:?}");
        assert!(
            (r - rest).abs() <= 1e-15 * rest,
            "{what}: rest length of {key:?}: {r} vs {rest}"
        );
    }
}

#[test]
fn classic_cube_springs_by_brute_force() {
    let want = brute_force([8, 8, 8], [1.0; 3]);
    // docs/spec.md's counts and rest lengths.
    let count = |kind| want.values().filter(|(k, _)| *k == kind).count();
    assert_eq!(count(SpringKind::Structural), 1344);
    assert_eq!(count(SpringKind::Shear), 3724);
    assert_eq!(count(SpringKind::Bend), 1152);
    assert_eq!(want.len(), 6220);
    let s2 = 2f64.sqrt();
    let s3 = 3f64.sqrt();
    for (key, (kind, rest)) in &want {
        let allowed: &[f64] = match kind {
            SpringKind::Structural => &[1.0 / 7.0],
            SpringKind::Shear => &[s2 / 7.0, s3 / 7.0],
            SpringKind::Bend => &[2.0 / 7.0],
        };
        assert!(
            allowed.iter().any(|r| (rest - r).abs() <= 1e-15),
            "{key:?}: {kind:?} of rest length {rest}"
        );
    }

    let lattice = Lattice::classic();
    assert_same(&as_set(&box_springs(&lattice)), &want, "Body::springs");
    let model = ModelBuilder::new().build().unwrap();
    assert_same(&as_set(&model.springs()), &want, "Model::springs");
    assert_eq!(model.springs().count_by_kind(), [1344, 3724, 1152]);
    // The counts without a list, and the walk without one, say the same.
    assert_eq!(lattice.spring_count_by_kind(), [1344, 3724, 1152]);
    let mut walked = SpringSet::new();
    lattice.for_each_spring(|a, b, rest, kind| {
        assert!(walked.insert((a.min(b), a.max(b)), (kind, rest)).is_none());
    });
    assert_same(&walked, &want, "Lattice::for_each_spring");
}

#[test]
fn other_lattices_springs_by_brute_force() {
    for (counts, size) in [
        ([2, 1, 1], [0.5, 1.0, 1.0]),
        ([1, 1, 5], [1.0, 1.0, 2.0]),
        ([3, 4, 5], [0.6, 1.1, 0.9]),
        ([6, 2, 3], [1.0, 0.25, 2.0]),
        ([4, 4, 1], [1.0, 1.0, 1.0]),
    ] {
        let want = brute_force(counts, size);
        let lattice = Lattice::new(counts, Vec3::new(size[0], size[1], size[2]));
        assert_same(
            &as_set(&box_springs(&lattice)),
            &want,
            &format!("{counts:?}"),
        );
    }
}

/// Accelerations of a deformed, moving lattice (no walls, field or plane touched) from the
/// brute-force set and docs/spec.md's law, `−k (|L| − R) L̂ − d ((vA − vB)·L̂) L̂` on A and the
/// opposite on B, against the force kernel. Per-kind constants differ, so a kind mix-up shows.
/// Tolerance 1e-12 of the largest acceleration: the sums differ only in rounding order.
#[test]
fn kernel_forces_match_the_brute_force_set() {
    let consts = [(200.0, 0.25), (130.0, 0.7), (55.0, 0.05)];
    for (counts, size) in [
        ([8, 8, 8], [1.0, 1.0, 1.0]),
        ([3, 4, 5], [0.6, 1.1, 0.9]),
        // Threaded in the kernel (13 824 points ≥ PARALLEL_MIN_POINTS) when `parallel` is on.
        ([24, 24, 24], [1.2, 1.0, 0.8]),
    ] {
        let lattice = Lattice::new(counts, Vec3::new(size[0], size[1], size[2]));
        let mut builder = ModelBuilder::new().lattice(lattice.clone()).mass(0.01);
        for (kind, (k, d)) in SpringKind::ALL.into_iter().zip(consts) {
            builder = builder.spring_kind(kind, k, d);
        }
        let model = builder.build().unwrap();
        let mut rng = Lcg(counts[0] as u64);
        let pos: Vec<Vec3> = lattice
            .rest_positions()
            .iter()
            .map(|p| *p - Vec3::new(0.5, 0.5, 0.5) + rng.vec3() * 0.02)
            .collect();
        let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3()).collect();
        let mut want = vec![Vec3::ZERO; pos.len()];
        let springs = if counts == [24, 24, 24] {
            // All pairs of 13 824 points is 10⁸: only the pairs within index distance 2.
            neighbours(counts, size)
        } else {
            brute_force(counts, size)
        };
        for (&(a, b), &(kind, rest)) in &springs {
            let (k, d) = consts[kind as usize];
            let l = pos[a] - pos[b];
            let len = l.length();
            let dir = l / len;
            let f = dir * (-k * (len - rest)) - dir * (d * (vel[a] - vel[b]).dot(dir));
            want[a] += f;
            want[b] -= f;
        }
        let want: Vec<Vec3> = want.iter().map(|f| *f / 0.01).collect();
        let mut got = vec![Vec3::ZERO; pos.len()];
        accelerations(&model, &pos, &vel, &Control::none(), &mut got);
        let scale = want.iter().map(|a| a.max_abs()).fold(0.0, f64::max);
        assert!(scale > 10.0);
        for (p, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!(
                (*g - *w).max_abs() <= 1e-12 * scale,
                "{counts:?}, point {p}: {g:?} vs {w:?}"
            );
        }
    }
}

/// The same classification as [`brute_force`], over the pairs within index distance 2 of each
/// other only (every spring is), for lattices too large for all pairs.
fn neighbours(counts: [usize; 3], size: [f64; 3]) -> SpringSet {
    let [nx, ny, nz] = counts;
    let index = |[i, j, k]: [usize; 3]| (i * ny + j) * nz + k;
    let near = |c: usize, n: usize| c.saturating_sub(2)..(c + 3).min(n);
    let h = spacing(counts, size);
    let mut set = SpringSet::new();
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                for i2 in near(i, nx) {
                    for j2 in near(j, ny) {
                        for k2 in near(k, nz) {
                            let (pa, pb) = ([i, j, k], [i2, j2, k2]);
                            if index(pa) >= index(pb) {
                                continue;
                            }
                            if let Some(spring) = classify(pa, pb, h) {
                                set.insert((index(pa), index(pb)), spring);
                            }
                        }
                    }
                }
            }
        }
    }
    set
}

/// The near-pairs shortcut finds what the brute force finds.
#[test]
fn near_pairs_are_all_pairs() {
    for counts in [[8, 8, 8], [3, 4, 5], [6, 1, 7]] {
        let size = [1.0, 0.7, 1.3];
        assert_eq!(
            neighbours(counts, size),
            brute_force(counts, size),
            "{counts:?}"
        );
    }
}
