//! The points Python sees: those that take part in the simulation.
//!
//! A body voxelised from a mesh keeps a whole regular lattice, so that point `(i, j, k)` has a
//! fixed flat index; the lattice points outside its kept cells are placeholders that never move
//! (`jello info` does not count them). `positions`, `velocities`, `control_forces`, `len(sim)`
//! and `bodies` show only the active points, in lattice order, so that a mean, a plot or a
//! count is the body's; `lattice_positions` and `active` give the whole lattice and its mask.
//! A classic world and box bodies have every point active: there the two views are the same.

use std::ops::Range;

use jello_core::{Model, Vec3};

/// Which of a model's points are active, and where each body's lie among them.
#[derive(Clone, Debug)]
pub(crate) struct ActivePoints {
    /// The model-wide indices of the active points, in order; `None` when every point is.
    indices: Option<Vec<usize>>,
    /// Points in the model, active or not.
    lattice_len: usize,
    /// Per body, its active points' range among the active points.
    body_ranges: Vec<Range<usize>>,
}

impl ActivePoints {
    /// The active points of `model`.
    pub(crate) fn of(model: &Model) -> Self {
        let mut indices = Vec::new();
        let mut body_ranges = Vec::with_capacity(model.bodies().len());
        for body in model.bodies() {
            let start = indices.len();
            let first = body.points().start;
            indices.extend(
                (0..body.len())
                    .filter(|&p| body.is_active(p))
                    .map(|p| first + p),
            );
            body_ranges.push(start..indices.len());
        }
        let lattice_len = model.point_count();
        ActivePoints {
            indices: (indices.len() < lattice_len).then_some(indices),
            lattice_len,
            body_ranges,
        }
    }

    /// Number of active points.
    pub(crate) fn len(&self) -> usize {
        self.indices.as_ref().map_or(self.lattice_len, Vec::len)
    }

    /// Each body's range in the arrays of active points.
    pub(crate) fn body_ranges(&self) -> &[Range<usize>] {
        &self.body_ranges
    }

    /// The active points' entries of `all` (one per lattice point).
    pub(crate) fn gather(&self, all: &[Vec3]) -> Vec<Vec3> {
        match &self.indices {
            None => all.to_vec(),
            Some(indices) => indices.iter().map(|&p| all[p]).collect(),
        }
    }

    /// `values` (one per active point) written into `all` (one per lattice point); the other
    /// entries of `all` stay.
    pub(crate) fn scatter(&self, values: Vec<Vec3>, all: &mut Vec<Vec3>) {
        match &self.indices {
            None => *all = values,
            Some(indices) => {
                for (&p, v) in indices.iter().zip(values) {
                    all[p] = v;
                }
            }
        }
    }

    /// The row of `positions` of lattice point `p` (model-wide flat index); `None` for an
    /// inactive point.
    pub(crate) fn row_of(&self, p: usize) -> Option<usize> {
        match &self.indices {
            None => (p < self.lattice_len).then_some(p),
            Some(indices) => indices.binary_search(&p).ok(),
        }
    }

    /// Per lattice point, whether it is active.
    pub(crate) fn mask(&self) -> Vec<bool> {
        match &self.indices {
            None => vec![true; self.lattice_len],
            Some(indices) => {
                let mut mask = vec![false; self.lattice_len];
                indices.iter().for_each(|&p| mask[p] = true);
                mask
            }
        }
    }
}
