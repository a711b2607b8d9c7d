//! Tests of the stencil-ordered matrix: its products, diagonal and blocks against the same
//! quantities summed spring by spring, and its ranges against rows computed at once.

use super::super::test_models::{box_at, on_threads, two_bodies, values, with_holes};
use super::*;
use crate::model::ModelBuilder;

/// A matrix with `model`'s springs listed as the solver lists them (entry by entry, each body
/// by body), and their ends (flat indices) in that order, the slot order.
fn listed(model: &Model) -> (SpringMatrix, Vec<[usize; 2]>) {
    let mut matrix = SpringMatrix::new(model);
    let mut springs = Vec::new();
    matrix.begin();
    for entry in 0..STENCIL.len() {
        for body in model.bodies() {
            let first = body.points().start;
            body.for_each_spring_of_entry(entry, |s| {
                matrix.push(first + s.a, entry);
                springs.push([first + s.a, first + s.b]);
            });
        }
    }
    matrix.finish();
    (matrix, springs)
}

/// Three bodies of about 9 000 points in all: a lattice with holes (drawn from `seed`), a full
/// box beside it and the small body with holes of [`two_bodies`].
fn three_bodies(seed: u64) -> Model {
    let holes = with_holes([16, 15, 14], seed, -0.7);
    let cube = box_at([14, 13, 12], Vec3::new(20.0, 0.0, 0.0));
    ModelBuilder::new()
        .bodies(vec![holes, cube, two_bodies().body(0).clone()])
        .build()
        .unwrap()
}

/// The solver's listing (entry by entry) has every spring the bodies list point by point, with
/// the same values: on bodies with holes (their links) and with springs' factors (their table).
#[test]
fn listing_entry_by_entry_lists_every_spring_once() {
    let mut next = values(5);
    for body in super::super::test_models::holes_and_factors(&mut next) {
        let key = |s: &crate::model::springs::Spring, entry: usize| {
            let values = [s.rest, s.stiffness, s.damping].map(f64::to_bits);
            (entry, s.a, s.b, s.kind, values)
        };
        let mut by_point = Vec::new();
        body.for_each_spring_entry(|s, entry| by_point.push(key(s, entry)));
        let mut by_entry = Vec::new();
        for entry in 0..STENCIL.len() {
            body.for_each_spring_of_entry(entry, |s| by_entry.push(key(s, entry)));
        }
        assert!(by_entry
            .windows(2)
            .all(|w| (w[0].0, w[0].1) < (w[1].0, w[1].1)));
        by_point.sort_by_key(|k| (k.0, k.1));
        assert_eq!(by_entry, by_point);
        assert!(
            by_entry.len() < body.len() * STENCIL.len(),
            "the holes cut springs"
        );
    }
}

#[test]
fn the_stencil_product_is_the_product_over_springs() {
    let model = two_bodies();
    let n = model.point_count();
    let mut next = values(11);
    let mut sym = || -> Sym { std::array::from_fn(|_| next()) };
    let (mut matrix, springs) = listed(&model);
    let blocks: Vec<Sym> = springs.iter().map(|_| sym()).collect();
    for (i, b) in blocks.iter().enumerate() {
        matrix.set(i, b);
    }
    let own: Vec<Sym> = (0..n).map(|_| sym()).collect();
    let free: Vec<f64> = (0..n).map(|i| if i % 7 == 3 { 0.0 } else { 1.0 }).collect();
    let mut next = values(13);
    let x: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();

    let product = |round: fn(f64) -> f64| -> Vec<Vec3> {
        let mut y: Vec<Vec3> = own.iter().zip(&x).map(|(m, &x)| sym_mul(m, x)).collect();
        for (&[a, b], m) in springs.iter().zip(&blocks) {
            let f = sym_mul(&m.map(round), x[a] - x[b]);
            y[a] += f;
            y[b] -= f;
        }
        y.iter().zip(&free).map(|(&y, &f)| y * f).collect()
    };
    let (exact, rounded) = (product(|v| v), product(|v| f64::from(v as f32)));
    let mut y = vec![Vec3::ZERO; n];
    matrix.set_own(&own);
    matrix.apply(&free, &x, &mut y, Precision::Double);
    for p in 0..n {
        let want = exact[p];
        assert!(
            (y[p] - want).max_abs() < 1e-12,
            "point {p}: {:?} ≠ {want:?}",
            y[p]
        );
    }
    // In single precision: the blocks rounded, and the sums with a relative error of about
    // 1e-7 (the values are of order 1), so not the exact product.
    matrix.apply(&free, &x, &mut y, Precision::Single);
    for p in 0..n {
        let want = rounded[p];
        assert!(
            (y[p] - want).max_abs() < 1e-5,
            "point {p}: {:?} ≠ {want:?}",
            y[p]
        );
    }
    assert!((0..n).any(|p| (y[p] - exact[p]).max_abs() > 1e-12));

    // A spring list that changes leaves no stale block behind.
    matrix.begin();
    matrix.push(0, 2);
    matrix.finish();
    matrix.set(0, &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
    let zero = vec![[0.0; 6]; n];
    matrix.set_own(&zero);
    matrix.apply(&free, &x, &mut y, Precision::Double);
    let mut want = vec![Vec3::ZERO; n];
    let lattice = model.body(0).lattice();
    let b = lattice.index(0, 0, 1);
    want[0] = x[0] - x[b];
    want[b] = x[b] - x[0];
    for p in 0..n {
        assert!((y[p] - want[p] * free[p]).max_abs() < 1e-15, "point {p}");
    }
}

/// The diagonal in stencil order is `own` plus each spring's block (rounded to single precision)
/// at both its ends, on lattices with holes, several bodies and more points than a pass takes,
/// with the same bits on any number of threads (chunks of 2 048 points over a team).
#[test]
fn the_diagonal_by_slot_is_the_sum_over_springs() {
    use super::super::sym::add_sym;
    let model = three_bodies(29);
    let n = model.point_count();
    assert!(
        n > 2 * MIN_POINTS_PER_RANGE,
        "{n} points: more than one chunk"
    );
    let (mut matrix, springs) = listed(&model);
    let mut next = values(29);
    let mut sym = || -> Sym { std::array::from_fn(|_| next()) };
    let blocks: Vec<Sym> = springs.iter().map(|_| sym()).collect();
    for (i, b) in blocks.iter().enumerate() {
        matrix.set(i, b);
    }
    let own: Vec<Sym> = (0..n).map(|_| sym()).collect();
    let mut want = own.clone();
    for (&[a, b], m) in springs.iter().zip(&blocks) {
        // From the blocks in single precision.
        let m = m.map(|m| f64::from(m as f32));
        add_sym(&mut want[a], &m);
        add_sym(&mut want[b], &m);
    }
    matrix.set_own(&own);
    let run = |threads: usize| {
        let mut diag = vec![[0.0; 6]; n];
        on_threads(threads, || matrix.diagonal(&mut diag));
        diag
    };
    let one = run(1);
    for (p, (d, w)) in one.iter().zip(&want).enumerate() {
        let error = d
            .iter()
            .zip(w)
            .map(|(d, w)| (d - w).abs())
            .fold(0.0, f64::max);
        assert!(error < 1e-12, "point {p}: {d:?} ≠ {w:?}");
    }
    let bits = |d: &[Sym]| d.iter().map(|m| m.map(f64::to_bits)).collect::<Vec<_>>();
    for threads in [2, 3] {
        assert_eq!(bits(&run(threads)), bits(&one), "{threads} threads");
    }
}

/// The blocks assembled by slot are each spring's block as [`super::super::spring_block`]
/// forms it with its damper at the start, rounded to single precision, and to the bit in double
/// precision once a product asks for that (a spring of zero length too), each assembly's; and
/// the start directions are each spring's.
#[test]
fn blocks_by_slot_are_the_blocks_of_each_spring() {
    use super::super::matrix::spring_block;
    use super::super::sym::add_outer;
    let model = two_bodies();
    let n = model.point_count();
    let (mut matrix, springs) = listed(&model);
    let mut next = values(23);
    let values: Vec<[f64; 3]> = springs
        .iter()
        .map(|_| [1.0 + next(), 100.0 * (2.0 + next()), 1.0 + next()])
        .collect();
    for (i, &[rest, k, d]) in values.iter().enumerate() {
        matrix.set_spring(i, rest, k, d);
    }
    let mut random = || Vec3::new(next(), next(), next());
    let mut x0: Vec<Vec3> = (0..n).map(|_| random()).collect();
    let v: Vec<Vec3> = (0..n).map(|_| random()).collect();
    let h = 0.1;
    // The first spring has zero length at the start and at the end.
    let [a, b] = springs[0];
    x0[b] = x0[a];
    let mut v = v;
    v[b] = v[a];
    let mut directions = vec![Vec3::ZERO; springs.len()];
    matrix.start_dampers(&x0);
    matrix.start_directions(&mut directions);
    for floor in [f64::MIN, 0.0] {
        matrix.assemble(&x0, &v, h, floor);
        let blocks = by_spring(&matrix, springs.len());
        let mut by_slot = Vec::new();
        for (i, (&[a, b], &[rest, k, d])) in springs.iter().zip(&values).enumerate() {
            let d0 = x0[a] - x0[b];
            let l0 = d0.length();
            let u0 = if l0 > 0.0 { d0 / l0 } else { Vec3::ZERO };
            assert_eq!(directions[i], u0, "spring {i}");
            let e = (x0[a] + v[a] * h) - (x0[b] + v[b] * h);
            let l = e.length();
            let mut want = [0.0; 6];
            if l > 0.0 {
                let transverse = h * h * k * (1.0 - rest / l).max(floor);
                want = spring_block(e / l, h * h * k, transverse);
            }
            // The damper as `h·(d/|L₀|²)·L₀L₀ᵀ`.
            let c = if l0 > 0.0 { d / d0.dot(d0) } else { 0.0 };
            add_outer(&mut want, d0, h * c);
            let bits = |m: &Sym| m.map(f64::to_bits);
            let rounded = want.map(|w| f64::from(w as f32));
            assert_eq!(
                bits(&blocks[i]),
                bits(&rounded),
                "spring {i}, floor {floor}"
            );
            let slot = matrix.slot[i] as usize;
            let single: [f32; 6] = std::array::from_fn(|c| matrix.blocks_single[c][slot]);
            assert_eq!(single, want.map(|w| w as f32), "spring {i}'s rounded block");
            by_slot.push((slot, want));
        }
        // In double precision when a product asks for them.
        let slot = by_slot[1].0;
        assert!(floor != f64::MIN || (0..6).all(|c| matrix.blocks[c][slot] == 0.0));
        let (own, free) = (vec![[0.0; 6]; n], vec![1.0; n]);
        let (x, mut y) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        matrix.set_own(&own);
        matrix.apply(&free, &x, &mut y, Precision::Double);
        for (slot, want) in by_slot {
            let by_slot: Sym = std::array::from_fn(|c| matrix.blocks[c][slot]);
            assert_eq!(
                by_slot.map(f64::to_bits),
                want.map(f64::to_bits),
                "slot {slot}"
            );
        }
    }
    // An assembly puts them behind again: at other end positions, the blocks of those.
    let v2: Vec<Vec3> = v.iter().map(|&v| v * 3.0).collect();
    matrix.assemble(&x0, &v2, h, 0.0);
    let blocks = by_spring(&matrix, springs.len());
    let (own, free) = (vec![[0.0; 6]; n], vec![1.0; n]);
    let (x, mut y) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    matrix.set_own(&own);
    matrix.apply(&free, &x, &mut y, Precision::Double);
    for (s, block) in blocks.iter().enumerate() {
        let slot = matrix.slot[s] as usize;
        let double: Sym = std::array::from_fn(|c| matrix.blocks[c][slot]);
        assert_eq!(
            double.map(|b| f64::from(b as f32)),
            *block,
            "spring {s} after v changed"
        );
    }
}

/// Rows computed in ranges (as threads compute them) have the bits of rows computed at
/// once, wherever the ranges start: inside a body, across a body's end, within one stencil
/// offset of the next range; whatever the tile, as long as it is the same.
#[test]
fn rows_in_ranges_have_the_bits_of_rows_at_once() {
    let model = two_bodies();
    let n = model.point_count();
    let (mut matrix, _) = listed(&model);
    let mut next = values(17);
    for s in 0..matrix.slot.len() {
        matrix.set(s, &std::array::from_fn(|_| next()));
    }
    let own: Vec<Sym> = (0..n).map(|_| std::array::from_fn(|_| next())).collect();
    let x: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
    let (mut x64, mut x32) = (Default::default(), Default::default());
    load::<f64>(&mut matrix.x, &x);
    std::mem::swap(&mut x64, &mut matrix.x);
    load::<f32>(&mut matrix.x_single, &x);
    std::mem::swap(&mut x32, &mut matrix.x_single);
    let second = model.body(1).points().start;
    let cuts = [
        vec![1],
        vec![7, 8, 40],
        vec![second - 1, second + 3],
        vec![n / 2],
    ];
    // The points' own part: in single precision from its own copy, as structure of arrays.
    matrix.set_own(&own);
    let own_single = &matrix.own_single;
    let single_own = |start: usize, out: [&mut [f32]; 3]| {
        let len = out[0].len();
        own_rows_soa(part(own_single, start, len), part(&x32, start, len), out);
    };
    let own = |start: usize, out: [&mut [f64]; 3]| {
        f64::own_rows(start, &|p: usize| sym_mul(&own[p], x[p]), out);
    };
    // Rows `range` of the blocks' product in single and in double precision, in tiles of
    // `tile` springs, as bits.
    let rows_of = |range: std::ops::Range<usize>, tile: usize| -> Vec<u64> {
        let start = range.start;
        let mut single: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; range.len()]);
        let mut double: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; range.len()]);
        let mut forces32 = std::array::from_fn(|_| vec![0.0; n]);
        let mut forces64 = std::array::from_fn(|_| vec![0.0; n]);
        let spans = &matrix.spans;
        let [a, b, c] = &mut single;
        let blocks = entry_forces(spring_forces_single, &matrix.blocks_single);
        rows(
            spans,
            n,
            single_own,
            &x32,
            start,
            [a, b, c],
            &mut forces32,
            tile,
            blocks,
        );
        let [a, b, c] = &mut double;
        let blocks = entry_forces(spring_forces, &matrix.blocks);
        rows(
            spans,
            n,
            own,
            &x64,
            start,
            [a, b, c],
            &mut forces64,
            tile,
            blocks,
        );
        let single = single.iter().flatten().map(|v| u64::from(v.to_bits()));
        let double = double.iter().flatten().map(|v| v.to_bits());
        single.chain(double).collect()
    };
    for tile in [1, 5, 64, TILE] {
        let whole = rows_of(0..n, tile);
        for cuts in &cuts {
            let mut bounds = vec![0];
            bounds.extend(cuts);
            bounds.push(n);
            let mut parts: Vec<Vec<u64>> = bounds
                .windows(2)
                .map(|w| rows_of(w[0]..w[1], tile))
                .collect();
            // Each part is its rows' three axes of each product: regroup as the whole is.
            let mut joined = Vec::new();
            for block in 0..6 {
                for (w, part) in bounds.windows(2).zip(&mut parts) {
                    let len = w[1] - w[0];
                    joined.extend_from_slice(&part[block * len..(block + 1) * len]);
                }
            }
            assert_eq!(joined, whole, "tile {tile}, cut at {cuts:?}");
        }
    }
}

/// A product's ranges cover the rows in order, one a thread, and the first, whose springs all
/// start in it, takes as many more rows as the others compute springs from before them: each
/// range reads as many blocks.
#[test]
fn the_ranges_of_a_product_read_as_many_blocks_each() {
    let model = ModelBuilder::new()
        .bodies(vec![box_at([24, 20, 22], Vec3::ZERO)])
        .build()
        .unwrap();
    let spans = SpringMatrix::spans_of(&model);
    let n = model.point_count();
    let span = spans[0];
    let offsets = || span.offset.iter().filter(|&&o| o != 0 && o < span.len);
    for threads in [1, 2, 3] {
        let (team, (starts, count)) =
            on_threads(threads, || (team::threads(), Ranges::starts(n, &spans)));
        let starts = &starts[..count];
        assert_eq!(count, team, "{threads} threads");
        assert_eq!(starts[0], 0);
        // Each range's blocks: its rows' and the springs reaching them from before it.
        let blocks: Vec<usize> = (starts.iter().enumerate())
            .map(|(r, &start)| {
                let end = starts.get(r + 1).copied().unwrap_or(n);
                let halo: usize = offsets().map(|&o| o.min(start)).sum();
                16 * (end - start) + halo
            })
            .collect();
        let (least, most) = (blocks.iter().min().unwrap(), blocks.iter().max().unwrap());
        assert!(most - least <= 32, "{threads} threads: {blocks:?}");
        if team > 1 {
            assert!(
                starts[1] > n / team,
                "the first range has more rows: {starts:?}"
            );
        }
    }
}

/// The blocks of the last assembly by spring (in slot order), as the multigrid reads them.
fn by_spring(matrix: &SpringMatrix, springs: usize) -> Vec<Sym> {
    let blocks = matrix.blocks_by_spring();
    (0..springs).map(|s| blocks.get(s)).collect()
}

/// The single-precision solvers' product reads the springs' blocks in 16 bits: each stencil
/// entry's blocks of a tile of first ends in whole steps of the tile's largest component over
/// `i16::MAX`, rounded to the nearest. It is the product with the blocks so rounded (to single
/// precision's sums), not the single-precision blocks', on bodies with holes, several bodies
/// and more points than a tile or a range holds; the same bits on any number of threads.
#[test]
fn the_packed_product_is_the_product_with_each_tiles_blocks_in_its_steps() {
    let model = three_bodies(31);
    let n = model.point_count();
    assert!(
        n > 2 * MIN_POINTS_PER_RANGE,
        "{n} points: ranges on 2 threads"
    );
    let (mut matrix, springs) = listed(&model);
    let mut next = values(37);
    // Blocks of different sizes from tile to tile (and zero in some), as a lattice's do.
    let blocks: Vec<Sym> = (springs.iter().enumerate())
        .map(|(i, _)| {
            let size = [0.0, 1e-3, 1.0, 40.0][(matrix.slot[i] as usize / TILE) % 4];
            std::array::from_fn(|_| size * next())
        })
        .collect();
    for (i, b) in blocks.iter().enumerate() {
        matrix.set(i, b);
    }
    matrix.pack();
    let own: Vec<Sym> = (0..n).map(|_| std::array::from_fn(|_| next())).collect();
    matrix.set_own(&own);
    let free: Vec<f64> = (0..n).map(|i| if i % 7 == 3 { 0.0 } else { 1.0 }).collect();
    let x: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();

    // Each tile's largest single-precision component (a tile: an entry's slots `e·n + t·TILE`
    // onwards), then each block in its tile's steps.
    let tile_of = |i: usize| {
        let slot = matrix.slot[i] as usize;
        (slot / n, (slot % n) / TILE)
    };
    let mut largest = std::collections::HashMap::new();
    for (i, b) in blocks.iter().enumerate() {
        let most = largest.entry(tile_of(i)).or_insert(0.0f32);
        *most = b.iter().fold(*most, |m, &v| m.max((v as f32).abs()));
    }
    let max = f32::from(i16::MAX);
    let packed = |i: usize, b: &Sym| -> Sym {
        let most = largest[&tile_of(i)];
        let (step, scale) = if most > 0.0 {
            (most / max, max / most)
        } else {
            (0.0, 0.0)
        };
        b.map(|v| f64::from(((v as f32) * scale).round_ties_even() * step))
    };
    let mut want: Vec<Vec3> = own.iter().zip(&x).map(|(m, &x)| sym_mul(m, x)).collect();
    let mut single = want.clone();
    for (i, (&[a, b], m)) in springs.iter().zip(&blocks).enumerate() {
        let f = sym_mul(&packed(i, m), x[a] - x[b]);
        (want[a], want[b]) = (want[a] + f, want[b] - f);
        let f = sym_mul(&m.map(|v| f64::from(v as f32)), x[a] - x[b]);
        (single[a], single[b]) = (single[a] + f, single[b] - f);
    }

    let run = |threads: usize, matrix: &mut SpringMatrix| {
        let [x0, x1, x2] = matrix.single_input();
        for (p, x) in x.iter().enumerate() {
            (x0[p], x1[p], x2[p]) = (x.x as f32, x.y as f32, x.z as f32);
        }
        let mut y: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        on_threads(threads, || {
            matrix.apply_single(&free, y.each_mut().map(|y| &mut y[..]));
        });
        y
    };
    let one = run(1, &mut matrix);
    let mut off_single = 0.0f64;
    for p in 0..n {
        let y = Vec3::new(one[0][p].into(), one[1][p].into(), one[2][p].into());
        // Sums of about 30 terms of up to 40·2·2 in single precision: 1e-4 apart at most.
        let error = (y - want[p] * free[p]).max_abs();
        assert!(error < 1e-4, "point {p}: {y:?} ≠ {:?}", want[p] * free[p]);
        off_single = off_single.max((y - single[p] * free[p]).max_abs());
    }
    // Steps of 40/32 767 are far coarser than single precision's rounding.
    assert!(
        off_single > 1e-3,
        "{off_single}: the single-precision blocks' product"
    );
    for threads in [2, 3] {
        let y = run(threads, &mut matrix);
        let bits = |y: &[Vec<f32>; 3]| {
            y.each_ref()
                .map(|y| y.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
        };
        assert_eq!(bits(&y), bits(&one), "{threads} threads");
    }
    // Where the solver does not allow them (a swirling field), or below `PACKED_FROM` points
    // (this model's), the single-precision blocks' product.
    assert!(n < PACKED_FROM);
    for may in [false, true] {
        matrix.pack_products(may);
        let y = run(1, &mut matrix);
        for p in 0..n {
            let y = Vec3::new(y[0][p].into(), y[1][p].into(), y[2][p].into());
            let error = (y - single[p] * free[p]).max_abs();
            assert!(error < 1e-4, "point {p}: {y:?} ≠ {:?}", single[p] * free[p]);
        }
    }
}
