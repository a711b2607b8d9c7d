//! Frames of a run written as files: PLY or OBJ meshes of the surface (each body's skin, or its
//! cage with every lattice point as a vertex), or CSV of every active point.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::ValueEnum;
use jello_core::formats::world::{significant, Num};
use jello_core::surface::{CageVertices, Surface};
use jello_core::{Model, State, Vec3};

use crate::error::CliError;
use jello_io::write_atomic;

/// File format of the frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FrameFormat {
    /// ASCII PLY: each body's skin, or every lattice point as a vertex with the cage surface as
    /// triangles.
    Ply,
    /// Wavefront OBJ: the same mesh as PLY.
    Obj,
    /// CSV: one row per active point with body, i, j, k, position and velocity.
    Csv,
}

impl FrameFormat {
    fn extension(self) -> &'static str {
        match self {
            FrameFormat::Ply => "ply",
            FrameFormat::Obj => "obj",
            FrameFormat::Csv => "csv",
        }
    }
}

/// Writes numbered frames into a folder.
pub struct FrameWriter {
    dir: PathBuf,
    format: FrameFormat,
    surface: Surface,
    /// Per body: its name, and where its triangles end in the surface's list (OBJ groups).
    bodies: Vec<(String, usize)>,
    positions: Vec<Vec3>,
    written: usize,
}

impl FrameWriter {
    /// Creates `dir` when missing; `names` are the bodies' (OBJ frames group each body's faces
    /// under its name).
    pub fn new(
        dir: &Path,
        format: FrameFormat,
        model: &Model,
        names: Vec<String>,
    ) -> Result<Self, CliError> {
        std::fs::create_dir_all(dir)
            .map_err(|e| CliError::io(format!("{}: cannot create folder: {e}", dir.display())))?;
        let surface = Surface::new(model, CageVertices::All);
        // The surface lists each body's triangles in turn, over its own vertices.
        let vertices = surface.body_vertices(model);
        let triangles = surface.triangles();
        let bodies = names
            .into_iter()
            .zip(&vertices)
            .map(|(name, range)| {
                let end = triangles.partition_point(|t| (t[0] as usize) < range.end);
                (name, end)
            })
            .collect();
        Ok(FrameWriter {
            dir: dir.to_path_buf(),
            format,
            surface,
            bodies,
            positions: Vec::new(),
            written: 0,
        })
    }

    /// Number of frames written so far.
    pub fn written(&self) -> usize {
        self.written
    }

    /// Writes `state` as the next frame, `frame_000000.ply` and so on.
    pub fn write(&mut self, model: &Model, state: &State) -> Result<(), CliError> {
        if self.format != FrameFormat::Csv {
            self.surface.positions(model, state, &mut self.positions);
        }
        let text = match self.format {
            FrameFormat::Ply => self.ply(state),
            FrameFormat::Obj => self.obj(state),
            FrameFormat::Csv => csv(model, state),
        };
        let path = self.dir.join(format!(
            "frame_{:06}.{}",
            self.written,
            self.format.extension()
        ));
        write_atomic(&path, text.as_bytes())?;
        self.written += 1;
        Ok(())
    }

    fn ply(&self, state: &State) -> String {
        let triangles = self.surface.triangles();
        let mut s = String::with_capacity(40 * self.positions.len() + 16 * triangles.len());
        let _ = write!(
            s,
            "ply\nformat ascii 1.0\ncomment jello frame, step {}, t = {} s\n\
             element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
             element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
            state.steps,
            header_time(state.time),
            self.positions.len(),
            triangles.len()
        );
        for p in &self.positions {
            let _ = writeln!(s, "{} {} {}", Num(p.x), Num(p.y), Num(p.z));
        }
        for [a, b, c] in triangles {
            let _ = writeln!(s, "3 {a} {b} {c}");
        }
        s
    }

    fn obj(&self, state: &State) -> String {
        let triangles = self.surface.triangles();
        let mut s = String::with_capacity(40 * self.positions.len() + 16 * triangles.len());
        let _ = writeln!(
            s,
            "# jello frame, step {}, t = {} s",
            state.steps,
            header_time(state.time)
        );
        for p in &self.positions {
            let _ = writeln!(s, "v {} {} {}", Num(p.x), Num(p.y), Num(p.z));
        }
        let mut start = 0;
        for (name, end) in &self.bodies {
            let _ = writeln!(s, "o {name}");
            for [a, b, c] in &triangles[start..*end] {
                let _ = writeln!(s, "f {} {} {}", a + 1, b + 1, c + 1);
            }
            start = *end;
        }
        s
    }
}

/// The time in a frame's header, a comment for people: to 12 significant digits, since the time
/// is summed step by step and its last bits are rounding (`2.9999999999997806` is shown `3`). The
/// positions are data and keep every digit (`Num`: the shortest form that reads back exactly).
fn header_time(time: f64) -> String {
    significant(time, 12)
}

/// One row per active point: a body voxelised from a mesh keeps a whole lattice for its indexing,
/// but its points outside the kept cells never move and are no part of the body (`jello info`
/// does not count them), so they are left out; `i,j,k` still place each row in the lattice.
fn csv(model: &Model, state: &State) -> String {
    let mut s = String::with_capacity(80 * state.len());
    s.push_str("body,i,j,k,x,y,z,vx,vy,vz\n");
    for (n, (p, v)) in state.pos.iter().zip(&state.vel).enumerate() {
        let (body, [i, j, k]) = model.locate(n);
        let own = model.body(body);
        if !own.is_active(n - own.points().start) {
            continue;
        }
        let _ = writeln!(
            s,
            "{},{i},{j},{k},{},{},{},{},{},{}",
            body + 1,
            Num(p.x),
            Num(p.y),
            Num(p.z),
            Num(v.x),
            Num(v.y),
            Num(v.z)
        );
    }
    s
}
