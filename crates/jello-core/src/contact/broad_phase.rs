//! The broad phase of contacts between bodies: the active points sorted into cubic grid cells
//! the size of the largest ball diameter, by a counting sort over a hash of the cell; each point
//! then looks at the 27 cells around its own. Buffers are sized once, so a pass allocates
//! nothing; the sort and the visits run in a fixed order, so the forces summed over them are bit
//! for bit the same whatever the thread count.

use crate::model::body::Body;

/// The active points of a model in a hashed uniform grid, sized once for a model.
#[derive(Clone, Debug, Default)]
pub(crate) struct BroadPhase {
    /// Bucket starts of the hashed grid (`buckets + 1` entries).
    starts: Vec<u32>,
    /// Active points sorted by bucket; in each bucket by index.
    entries: Vec<u32>,
    /// Per sorted entry: its grid cell.
    entry_cells: Vec<[i32; 3]>,
    /// Per sorted entry: its body.
    entry_body: Vec<u32>,
    /// Per point: its grid cell (for the sort).
    point_cells: Vec<[i32; 3]>,
    /// Side of a grid cell (m).
    cell: f64,
}

impl BroadPhase {
    /// A grid of cells of side `cell` (m) for `points` points of which `active` are active.
    pub(crate) fn new(points: usize, active: usize, cell: f64) -> Self {
        let buckets = (2 * active).next_power_of_two();
        BroadPhase {
            starts: vec![0; buckets + 1],
            entries: vec![0; active],
            entry_cells: vec![[0; 3]; active],
            entry_body: vec![0; active],
            point_cells: vec![[0; 3]; points],
            cell,
        }
    }

    /// Sorts the active points of `bodies`, at positions `[px, py, pz]`, into the grid.
    pub(crate) fn sort(&mut self, bodies: &[Body], [px, py, pz]: [&[f64]; 3]) {
        let BroadPhase {
            starts,
            entries,
            entry_cells,
            entry_body,
            point_cells,
            cell,
        } = self;
        let inv = 1.0 / *cell;
        let mask = starts.len() - 2;
        // Counting sort of the active points by bucket.
        starts.fill(0);
        for body in bodies {
            for q in active_points(body) {
                let c = [px[q], py[q], pz[q]].map(|x| (x * inv).floor() as i32);
                point_cells[q] = c;
                starts[hash(c) & mask] += 1;
            }
        }
        let mut sum = 0;
        for s in starts.iter_mut() {
            let count = *s;
            *s = sum;
            sum += count;
        }
        for (b, body) in bodies.iter().enumerate() {
            for q in active_points(body) {
                let c = point_cells[q];
                let slot = &mut starts[hash(c) & mask];
                let e = *slot as usize;
                (entries[e], entry_cells[e], entry_body[e]) = (q as u32, c, b as u32);
                *slot += 1;
            }
        }
        // Each bucket's start is now the next one's; shift back.
        for b in (1..starts.len()).rev() {
            starts[b] = starts[b - 1];
        }
        starts[0] = 0;
    }

    /// The grid cell of point `q` in the last [`BroadPhase::sort`].
    #[inline]
    pub(crate) fn cell_of(&self, q: usize) -> [i32; 3] {
        self.point_cells[q]
    }

    /// Calls `near(e, body of e)` for every active point `e` of a body other than `body` in the
    /// 27 grid cells around `cell`, in a fixed order.
    #[inline]
    pub(crate) fn for_each_near(
        &self,
        body: &Body,
        cell: [i32; 3],
        mut near: impl FnMut(usize, usize),
    ) {
        let mask = self.starts.len() - 2;
        let own = body.points();
        for n in 0..27 {
            let d = [n / 9 - 1, n / 3 % 3 - 1, n % 3 - 1];
            let around = [
                cell[0].wrapping_add(d[0]),
                cell[1].wrapping_add(d[1]),
                cell[2].wrapping_add(d[2]),
            ];
            let bucket = hash(around) & mask;
            let range = self.starts[bucket] as usize..self.starts[bucket + 1] as usize;
            let candidates = self.entries[range.clone()]
                .iter()
                .zip(&self.entry_cells[range.clone()])
                .zip(&self.entry_body[range]);
            for ((&e, &ec), &eb) in candidates {
                // Another cell hashed to the same bucket, or the same body: skip.
                let e = e as usize;
                if ec != around || own.contains(&e) {
                    continue;
                }
                near(e, eb as usize);
            }
        }
    }
}

/// The active points of a body, as flat indices of the model.
pub(crate) fn active_points(body: &Body) -> impl Iterator<Item = usize> + '_ {
    body.points()
        .filter(move |&q| body.is_active(q - body.points().start))
}

/// A hash of a grid cell (the three large primes of Teschner et al. 2003).
#[inline]
fn hash(c: [i32; 3]) -> usize {
    ((c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791)) as usize
}
