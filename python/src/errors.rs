//! The package's exceptions: `jello.BlowUp` for a step that blew up (or did not converge),
//! `jello.WorldError` for a file or a description that makes no valid simulation, and
//! `jello.GpuError` for a GPU that cannot be used or fails.

use std::path::Path;

use jello_core::BlowUpCause;
use pyo3::create_exception;
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError, PyRuntimeError,
    PyValueError,
};
use pyo3::prelude::*;

create_exception!(
    jello,
    BlowUp,
    PyRuntimeError,
    "A step blew up (a value went non-finite, a point left the box, or an implicit step did not \
     converge). The message is the `jello` command line's; the simulation stays at the last good \
     step. Attributes: step, time, point (the row of `positions`), body, integrator, dt, \
     suggested_dt (None when no time step would do), residual (None unless the implicit solve \
     did not converge)."
);

create_exception!(
    jello,
    WorldError,
    PyValueError,
    "A world file, scene file, mesh or description that makes no valid simulation; the message \
     names the file and the line (and the column in a scene file) and says what was expected. \
     Attribute: filename (None for a description built in Python)."
);

create_exception!(
    jello,
    GpuError,
    PyRuntimeError,
    "No usable GPU for `device=\"gpu\"` (no Vulkan, Metal or DX12 driver, nor Mesa's lavapipe; \
     or a lattice larger than the GPU's buffers allow), or the GPU failed while stepping (lost, \
     out of memory); the simulation keeps the last state read back from it, and the next step \
     on the GPU starts it again from there (or set `device = \"cpu\"`)."
);

/// `jello.WorldError(message)` with its `filename`.
pub fn world_error(py: Python<'_>, message: String, filename: Option<&str>) -> PyErr {
    let err = WorldError::new_err(message);
    // Setting an attribute on a fresh exception object cannot fail in practice; if it did, the
    // message still says everything.
    let _ = err.value(py).setattr("filename", filename);
    err
}

/// `jello.BlowUp` for `blow_up`, its message prefixed by the source's name as the CLI's is, and
/// its advice on the time step given the Python way (`sim.dt = …`, not the CLI's `--dt …`).
pub fn blow_up_error(py: Python<'_>, source: &str, blow_up: &jello_core::BlowUp) -> PyErr {
    let err = BlowUp::new_err(python_advice(format!("{source}: {blow_up}")));
    let value = err.value(py);
    let residual = match blow_up.cause {
        BlowUpCause::NotConverged { residual, .. } => Some(residual),
        _ => None,
    };
    let _ = value.setattr("step", blow_up.step);
    let _ = value.setattr("time", blow_up.time);
    let _ = value.setattr("point", blow_up.point);
    let _ = value.setattr("body", blow_up.body);
    let _ = value.setattr("integrator", blow_up.integrator.name());
    let _ = value.setattr("dt", blow_up.dt);
    let _ = value.setattr("suggested_dt", blow_up.suggested_dt);
    let _ = value.setattr("residual", residual);
    err
}

/// The core's advice on the time step, written for the command line (`try --dt 0.0011`, `try a
/// smaller --dt`), as a Python user follows it: `try sim.dt = 0.0011`, `try a smaller sim.dt`.
fn python_advice(message: String) -> String {
    message
        .replace("try --dt ", "try sim.dt = ")
        .replace("try a smaller --dt", "try a smaller sim.dt")
}

/// The Python exception for an input file that cannot be read at all (missing, a folder, no
/// permission): `FileNotFoundError` and its kin, as `open()` raises; `None` when it can be.
pub fn unreadable(path: &Path) -> Option<PyErr> {
    let name = path.display().to_string();
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Some(PyIsADirectoryError::new_err((
            21,
            "is a directory, expected a world (.w) or scene (.toml) file",
            name,
        ))),
        Ok(_) => None,
        Err(e) => {
            // "No such file or directory", without Rust's " (os error 2)".
            let text = e.to_string();
            let reason = text.split(" (os error").next().unwrap_or(&text).to_string();
            let args = (e.raw_os_error().unwrap_or(0), reason, name);
            Some(match e.kind() {
                std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(args),
                std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(args),
                _ => PyOSError::new_err(args),
            })
        }
    }
}

/// A failed write as `OSError`, naming the file.
pub fn write_error(message: String) -> PyErr {
    PyOSError::new_err(message)
}
