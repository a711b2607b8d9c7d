//! `jello run --export OUT.glb`: the run's surface (each body's skin, or the cage of a body
//! without one) as one animated binary glTF file (morph targets, see [`jello_io::gltf`]),
//! written atomically once the run succeeds.

use std::path::{Path, PathBuf};

use jello_core::surface::{CageVertices, Surface};
use jello_core::{Model, State, Vec3};
use jello_io::colours::body_colour;
use jello_io::gltf::{MeshAnimation, MeshPart, MAX_FRAMES};

use crate::error::CliError;
use jello_io::{check_writable_target, write_atomic};

/// Frames per simulated second of `--export`, and of `--frames` without `--every`: a film's rate
/// (a frame every step, the old default, wrote 1001 files and 59 MB for 1 s of a scene).
pub const DEFAULT_FPS: f64 = 30.0;

/// Steps between two frames at about `fps` frames per simulated second: `round(1/(fps·dt))`, at
/// least one.
pub fn steps_between_frames(fps: f64, dt: f64) -> u64 {
    (1.0 / (fps * dt)).round().max(1.0) as u64
}

/// Records frames of the model's surface while a run steps.
pub struct GlbExport {
    path: PathBuf,
    /// Steps between frames.
    every: u64,
    /// What is exported: skins and cages.
    surface: Surface,
    /// The surface's vertices in the current frame.
    positions: Vec<Vec3>,
    animation: MeshAnimation,
}

impl GlbExport {
    /// An export to `path` of a run of `steps` steps at about `fps` frames per simulated second
    /// (a frame every `round(1/(fps·dt))` steps, at least one, and the final state). Fails
    /// before the run when `path` cannot be written or the frames would be too many. Each body
    /// gets a material of its own named `names[b]`, coloured as the viewer colours it.
    pub fn new(
        path: &Path,
        model: &Model,
        names: &[String],
        fps: f64,
        steps: u64,
    ) -> Result<Self, CliError> {
        check_writable_target(path)?;
        let every = steps_between_frames(fps, model.dt);
        let frames = 1 + steps / every + u64::from(steps % every != 0);
        if frames > MAX_FRAMES as u64 {
            return Err(CliError::input(format!(
                "{}: {steps} steps at a frame every {every} would export {frames} frames, more \
                 than the {MAX_FRAMES} one glTF file holds: lower --fps or the run's length",
                path.display()
            )));
        }
        let surface = Surface::new(model, CageVertices::Used);
        if surface.triangles().is_empty() {
            return Err(CliError::input(format!(
                "{}: the lattice is flat and has no surface to export",
                path.display()
            )));
        }
        // The surface lists each body's triangles in turn, over its own vertices.
        let triangles = surface.triangles();
        let parts = (surface.body_vertices(model).iter().zip(names).enumerate())
            .map(|(b, (vertices, name))| MeshPart {
                name: name.clone(),
                triangles_end: triangles.partition_point(|t| (t[0] as usize) < vertices.end),
                colour: body_colour(b),
            })
            .collect();
        let animation = MeshAnimation::new(surface.vertex_count(), triangles.to_vec())
            .with_parts(parts)
            .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
        Ok(GlbExport {
            path: path.to_path_buf(),
            every,
            animation,
            surface,
            positions: Vec::new(),
        })
    }

    /// Steps between frames.
    pub fn every(&self) -> u64 {
        self.every
    }

    /// Records `state` as the next frame.
    pub fn record(&mut self, model: &Model, state: &State) -> Result<(), CliError> {
        self.surface.positions(model, state, &mut self.positions);
        self.animation
            .push(state.time, &self.positions)
            .map_err(|e| CliError::input(format!("{}: {e}", self.path.display())))
    }

    /// Number of frames recorded.
    pub fn frames(&self) -> usize {
        self.animation.len()
    }

    /// The file's bytes.
    pub fn bytes(&self, name: &str) -> Result<Vec<u8>, CliError> {
        self.animation
            .to_glb(name)
            .map_err(|e| CliError::io(format!("{}: {e}", self.path.display())))
    }

    /// Writes `bytes` (from [`GlbExport::bytes`]) to the file, atomically.
    pub fn write(&self, bytes: &[u8]) -> Result<(), CliError> {
        Ok(write_atomic(&self.path, bytes)?)
    }
}
