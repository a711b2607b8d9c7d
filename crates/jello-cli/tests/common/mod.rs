//! What the command-line test binaries share: a fresh temporary folder to run `jello` in.
#![allow(dead_code)]

use std::fs;
use std::path::PathBuf;
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

/// `jello create` of a 0.2 m cube of 3³ points resting on a 5 cm plate (`rest.toml`): a scene
/// no warning should be about.
pub const CUBE_RESTING_ON_A_PLATE: &[&str] = &[
    "create",
    "rest.toml",
    "--cube",
    "3",
    "--size",
    "0.2",
    "--centre",
    "0,0,0.11",
    "--collision-stiffness",
    "1e4",
    "--collision-damping",
    "5",
    "--box=-1,-1,-0.05,1,1,0",
];

/// A fresh folder under the system temp dir, removed when dropped. Each test binary adds the
/// helpers it needs in an `impl TempDir` of its own.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// A new empty folder, named after the process, a counter and `label`.
    pub fn new(label: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!("jello-test-{}-{n}-{label}", std::process::id()));
        let _ = fs::remove_dir_all(&path);
        fs::create_dir_all(&path).unwrap();
        TempDir(path)
    }

    /// `name` in the folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Runs `jello ARGS` in the folder.
    pub fn run(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_jello"))
            .args(args)
            .current_dir(&self.0)
            .output()
            .expect("cannot start jello")
    }

    /// Runs `jello ARGS` in the folder; it must succeed. Returns its standard output.
    pub fn succeeds(&self, args: &[&str]) -> String {
        let out = self.run(args);
        assert!(
            out.status.success(),
            "jello {}\n{}{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}
