//! `jello view` as a browser sees it: raw HTTP requests to the server the binary starts on
//! 127.0.0.1, over a stand-in viewer folder (the real bundle is tested by web/tests).

use std::fs;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// A running `jello view`, stopped when dropped.
struct Server {
    child: Child,
    port: u16,
    dist: PathBuf,
}

impl Server {
    fn start(label: &str, extra: &[&str]) -> Server {
        let dist = std::env::temp_dir().join(format!("jello-view-{label}-{}", std::process::id()));
        fs::create_dir_all(dist.join("assets")).unwrap();
        fs::write(
            dist.join("index.html"),
            "<!doctype html><title>Jello</title>",
        )
        .unwrap();
        fs::write(dist.join("assets/app.wasm"), b"\0asm").unwrap();
        fs::write(dist.join(".hidden"), "secret").unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_jello"))
            .arg("view")
            .args(extra)
            .args(["--port", "0", "--dist"])
            .arg(&dist)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let port = line
            .split("http://127.0.0.1:")
            .nth(1)
            .and_then(|rest| rest.split('/').next())
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no URL in {line:?}"));
        Server { child, port, dist }
    }

    /// Status line, headers and body of a raw request.
    fn request(&self, raw: &str) -> (u16, String, Vec<u8>) {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).unwrap();
        s.write_all(raw.as_bytes()).unwrap();
        let mut out = Vec::new();
        s.read_to_end(&mut out).unwrap();
        let split = out.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
        let head = String::from_utf8(out[..split].to_vec()).unwrap();
        let status = head[9..12].parse().unwrap();
        (status, head, out[split + 4..].to_vec())
    }

    fn get(&self, path: &str) -> (u16, String, Vec<u8>) {
        self.request(&format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n"))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = fs::remove_dir_all(&self.dist);
    }
}

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
}

#[test]
fn serves_the_viewer_config_world_and_examples() {
    let world = example("rotate.w");
    let server = Server::start("serves", &[world.to_str().unwrap()]);

    let (status, head, body) = server.get("/");
    assert_eq!(status, 200);
    assert!(head.contains("Content-Type: text/html"));
    assert!(String::from_utf8_lossy(&body).contains("<title>Jello</title>"));

    let (status, head, _) = server.get("/assets/app.wasm?v=1");
    assert_eq!(status, 200);
    assert!(head.contains("Content-Type: application/wasm"), "{head}");

    let (status, _, body) = server.get("/config.json");
    assert_eq!(status, 200);
    let config = String::from_utf8(body).unwrap();
    assert!(
        config.contains(r#""world": {"url": "world.w", "name": "rotate.w", "example": true}"#),
        "{config}"
    );
    assert!(config.contains(r#""jello.w""#) && config.contains(r#""spin.w""#));
    assert!(config.contains(r#""stack.toml""#) && config.contains(r#""torus.toml""#));
    let (status, head, body) = server.get("/examples/stack.toml");
    assert_eq!(status, 200);
    assert!(head.contains("Content-Type: text/plain"), "{head}");
    assert_eq!(body, fs::read(example("stack.toml")).unwrap());

    let (status, _, body) = server.get("/world.w");
    assert_eq!(status, 200);
    assert_eq!(body, fs::read(&world).unwrap());
    let (status, _, body) = server.get("/examples/jello.w");
    assert_eq!(status, 200);
    assert_eq!(body, fs::read(example("jello.w")).unwrap());

    let (status, head, body) = server.request("HEAD / HTTP/1.1\r\n\r\n");
    assert_eq!(status, 200);
    assert!(head.contains("Content-Length: ") && body.is_empty());
}

#[test]
fn a_users_own_file_is_not_taken_for_the_example_of_its_name() {
    // The user's own jello.w, in a folder of theirs: the page must list it as theirs, beside
    // the example jello.w.
    let dir = std::env::temp_dir().join(format!("jello-view-own-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    let own = dir.join("jello.w");
    fs::copy(example("rotate.w"), &own).unwrap();
    let server = Server::start("own", &[own.to_str().unwrap()]);
    let (_, _, body) = server.get("/config.json");
    fs::remove_dir_all(&dir).unwrap();
    let config = String::from_utf8(body).unwrap();
    assert!(
        config.contains(r#""world": {"url": "world.w", "name": "jello.w", "example": false}"#),
        "{config}"
    );
    assert!(
        config.contains(r#""jello.w""#),
        "the example is still listed: {config}"
    );
}

#[test]
fn refuses_what_it_should_not_serve() {
    let server = Server::start("refuses", &[]);
    for path in [
        "/../Cargo.toml",
        "/%2e%2e/Cargo.toml",
        "/assets/../../Cargo.toml",
        "/examples/../Cargo.toml",
        "/examples/missing.w",
        "/.hidden",
        "/assets/",
        "/world.w", // no world given
        "/%zz",
        "relative",
        "/..%5c..%5cCargo.toml",
    ] {
        assert_eq!(server.get(path).0, 404, "{path}");
    }
    let (status, head, _) = server.request("POST / HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
    assert_eq!(status, 405);
    assert!(head.contains("Allow: GET, HEAD"));
    assert_eq!(server.request("GARBAGE\r\n\r\n").0, 405);
    let (_, _, body) = server.get("/config.json");
    assert!(String::from_utf8(body)
        .unwrap()
        .contains(r#""world": null"#));
}

#[test]
fn a_bad_world_or_missing_build_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_jello"))
        .args(["view", "--port", "0", "--dist", "/nonexistent-jello-dist"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the viewer is not built"));

    let dir = std::env::temp_dir().join(format!("jello-view-bad-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join("index.html"), "x").unwrap();
    fs::write(dir.join("bad.w"), "RK4\n0.0005 1\nnope\n").unwrap();
    fs::write(dir.join("bad.toml"), "[simulation]\ndt = \"fast\"\n").unwrap();
    let view = |file: &str| {
        Command::new(env!("CARGO_BIN_EXE_jello"))
            .args(["view", "--port", "0", "--dist"])
            .arg(&dir)
            .arg(dir.join(file))
            .output()
            .unwrap()
    };
    let (world, scene) = (view("bad.w"), view("bad.toml"));
    fs::remove_dir_all(&dir).unwrap();
    assert_eq!(world.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&world.stderr).contains("bad.w:3:"));
    assert_eq!(scene.status.code(), Some(1));
    let said = String::from_utf8_lossy(&scene.stderr);
    assert!(said.contains("bad.toml:2:6:"), "{said}");
}
