//! # jello-io
//!
//! Files for Jello's faces (the `jello` command line and the Python package): bounded reads,
//! atomic writes, and a world (`.w`) or scene (`.toml`) loaded into a [`Simulation`] and saved
//! back. The core does no I/O; this crate is where the faces' file rules live, once. It also
//! writes animated meshes as binary glTF ([`gltf`]), which only the faces need.

#![warn(missing_docs)]

pub mod colours;
pub mod gltf;

use std::fmt;
use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use jello_core::{Integrator, ReadOptions, SceneFile, Simulation, World};

/// What went wrong with a file: bad input (unreadable, malformed) or a failed write.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileError {
    /// What happened, naming the file and line where there is one.
    pub message: String,
    /// Which kind of failure.
    pub kind: FileErrorKind,
}

/// The kinds of [`FileError`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileErrorKind {
    /// A file that cannot be read, or is not what was expected.
    Input,
    /// A file that cannot be written.
    Write,
}

impl FileError {
    /// Bad input.
    pub fn input(message: impl Into<String>) -> Self {
        FileError {
            message: message.into(),
            kind: FileErrorKind::Input,
        }
    }

    /// A failed write.
    pub fn io(message: impl Into<String>) -> Self {
        FileError {
            message: message.into(),
            kind: FileErrorKind::Write,
        }
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for FileError {}

/// Largest world file we read (bytes). A classic file with a 30³ field is under 1 MiB; this bound
/// keeps a wrong path (a device, a huge binary) from exhausting memory.
pub const MAX_WORLD_BYTES: u64 = 64 << 20;

/// What a simulation was read from: a classic world file or a TOML scene.
#[derive(Clone, Debug)]
pub enum Source {
    /// A `.w` world file.
    World(World),
    /// A `.toml` scene file.
    Scene(SceneFile),
}

impl Source {
    /// The file text that saves `sim`'s current state in this source's format: a world file, or
    /// the scene with every point's state.
    pub fn state_text(&self, sim: &Simulation) -> Result<String, String> {
        match self {
            Source::World(_) => sim
                .to_world()
                .map(|w| w.to_text())
                .map_err(|e| e.to_string()),
            Source::Scene(scene) => Ok(scene.with_state(&sim.model, &sim.state).to_toml()),
        }
    }
}

/// True when `path` names a scene file (`.toml`, any case).
pub fn is_scene(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// Reads a world file or, for a `.toml` name, a scene file, with the integrator and time step
/// replaced when given; errors name the file, the line (and the column for TOML).
pub fn load(
    path: &Path,
    integrator: Option<Integrator>,
    dt: Option<f64>,
) -> Result<(Simulation, Source), FileError> {
    refuse_mesh(path)?;
    let bytes = read_bounded(path)?;
    load_bytes(
        &bytes,
        &path.display().to_string(),
        is_scene(path),
        integrator,
        dt,
    )
}

/// [`load`] of a file's bytes: a scene file when `scene`, else a world file; `name` labels
/// errors.
pub fn load_bytes(
    bytes: &[u8],
    name: &str,
    scene: bool,
    integrator: Option<Integrator>,
    dt: Option<f64>,
) -> Result<(Simulation, Source), FileError> {
    if scene {
        let mut scene =
            SceneFile::parse(bytes, name).map_err(|e| FileError::input(e.to_string()))?;
        if let Some(i) = integrator {
            scene.simulation.integrator = i.name().to_string();
        }
        if let Some(dt) = dt {
            scene.simulation.dt = dt;
        }
        let made = scene
            .to_scene(name)
            .map_err(|e| FileError::input(e.to_string()))?;
        return Ok((
            Simulation::new(made.model, made.state),
            Source::Scene(scene),
        ));
    }
    let mut world = World::parse(bytes, name, ReadOptions { integrator })
        .map_err(|e| FileError::input(e.to_string()))?;
    if let Some(dt) = dt {
        world.dt = dt;
    }
    let sim =
        Simulation::from_world(&world).map_err(|e| FileError::input(format!("{name}: {e}")))?;
    Ok((sim, Source::World(world)))
}

/// An error for a mesh file (`.obj`, `.stl`) given where a world or scene is expected: read as a
/// world, its first letters would be taken for an integrator's name. The message says how to make
/// a scene of it.
pub fn refuse_mesh(path: &Path) -> Result<(), FileError> {
    let Some(extension) = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
    else {
        return Ok(());
    };
    let format = match extension.as_str() {
        "obj" => "a Wavefront OBJ mesh",
        "stl" => "an STL mesh",
        _ => return Ok(()),
    };
    let name = path.display();
    Err(FileError::input(format!(
        "{name}: this is {format}, not a world (.w) or scene (.toml); make a scene of it first, \
         e.g. `jello create scene.toml --mesh {name}` (see `jello create --help`), then run \
         the scene"
    )))
}

/// Reads and parses a world file; errors name the file and the line.
pub fn read_world(path: &Path, options: ReadOptions) -> Result<World, FileError> {
    let name = path.display().to_string();
    let bytes = read_bounded(path)?;
    World::parse(&bytes, &name, options).map_err(|e| FileError::input(e.to_string()))
}

/// The bytes of an input file, at most [`MAX_WORLD_BYTES`].
pub fn read_bounded(path: &Path) -> Result<Vec<u8>, FileError> {
    let name = path.display().to_string();
    let file =
        fs::File::open(path).map_err(|e| FileError::input(format!("{name}: cannot open: {e}")))?;
    if file.metadata().map(|m| m.is_dir()).unwrap_or(false) {
        return Err(FileError::input(format!(
            "{name}: is a directory, expected a file"
        )));
    }
    let mut bytes = Vec::new();
    file.take(MAX_WORLD_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| FileError::input(format!("{name}: cannot read: {e}")))?;
    if bytes.len() as u64 > MAX_WORLD_BYTES {
        return Err(FileError::input(format!(
            "{name}: larger than {} MiB, which no world or scene file is",
            MAX_WORLD_BYTES >> 20
        )));
    }
    Ok(bytes)
}

/// Writes `bytes` to `path` atomically: into a temporary file beside it, flushed to disk, then
/// renamed over `path`. Readers see the old file or the whole new one, never a part.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.display().to_string();
    let file_name = path
        .file_name()
        .ok_or_else(|| FileError::input(format!("{name}: not a file name")))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if path.is_dir() {
        return Err(FileError::io(format!("{name}: is a directory")));
    }
    let tmp = dir.join(format!(
        ".{}.tmp-{}-{}",
        file_name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = fs::remove_file(&tmp);
        FileError::io(format!("{name}: cannot write: {e}"))
    })
}

/// Checks that `path` may be written as a new output: its folder exists, and it does not exist
/// yet unless `force` (the `--force` flag) allows overwriting it.
pub fn check_new_output(path: &Path, force: bool) -> Result<(), FileError> {
    check_writable_target(path)?;
    if path.exists() && !force {
        return Err(FileError::input(format!(
            "{}: already exists (use --force to overwrite)",
            path.display()
        )));
    }
    Ok(())
}

/// Checks before a long run that `path` can later be written: its folder exists.
pub fn check_writable_target(path: &Path) -> Result<(), FileError> {
    let name = path.display().to_string();
    if path.is_dir() {
        return Err(FileError::input(format!(
            "{name}: is a directory, expected a file to write"
        )));
    }
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() && !d.is_dir() => Err(FileError::input(format!(
            "{name}: folder {} does not exist",
            d.display()
        ))),
        _ => Ok(()),
    }
}

// The user guide's Rust examples, compiled and run as this crate's doctests (`cargo test --doc
// -p jello-io`), so that every example in docs/ runs as printed. python/tests/test_docs.py
// checks that every Markdown page with Rust blocks is listed here.
#[cfg(doctest)]
#[doc = include_str!("../../../docs/rust.md")]
struct RustGuide;

#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
struct ReadmeTour;
