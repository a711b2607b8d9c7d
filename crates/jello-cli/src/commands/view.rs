//! `jello view`: serves the browser viewer (the built `web/dist`) on 127.0.0.1 only, with the
//! example worlds and, when given, the world to start with.
//!
//! The server is deliberately tiny: std's `TcpListener`, one thread per connection, `GET` and
//! `HEAD` only, one request per connection. Paths are percent-decoded and checked segment by
//! segment (no `..`, no hidden files, no backslashes), then resolved inside the served folder
//! (symbolic links out of it are refused). What it serves:
//!
//! | path | what |
//! | --- | --- |
//! | `/config.json` | `{"world": {"url", "name", "example"} or null, "examples": [names]}` for the page (`example`: the world is that example's file) |
//! | `/world.w` | the world or scene given on the command line (read and checked at start; the page reads it by the name in `config.json`) |
//! | `/examples/NAME` | an example world or scene from the source tree's `examples/` |
//! | anything else | a file of the built viewer, `/` meaning `index.html` |

use std::fs;
use std::io::{self, BufWriter, Read, Write};
use std::net::{Ipv4Addr, SocketAddrV4, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use clap::Args;

use crate::error::CliError;
use jello_io::load;

/// Port used when `--port` is not given.
pub const DEFAULT_PORT: u16 = 7878;
/// Longest request head read (bytes); a browser's GET is well under this.
const MAX_REQUEST_HEAD: usize = 16 * 1024;
/// Connections served at once; more get `503` (a local viewer needs a handful).
const MAX_CONNECTIONS: usize = 64;
/// How long a connection may take to send its request.
const READ_TIMEOUT: Duration = Duration::from_secs(10);

/// Arguments of `jello view`.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ViewArgs {
    /// World (.w) or scene (.toml) file to start with [default: the classic examples/jello.w].
    pub world: Option<PathBuf>,
    /// Port on 127.0.0.1 to serve on; 0 picks a free one.
    #[arg(long, short, default_value_t = DEFAULT_PORT)]
    pub port: u16,
    /// Open the viewer in the default browser (with xdg-open).
    #[arg(long)]
    pub open: bool,
    /// Folder of the built viewer [default: web/dist of the source tree this binary was built
    /// from].
    #[arg(long, value_name = "DIR")]
    pub dist: Option<PathBuf>,
}

/// Everything the server hands out, fixed at start.
struct Site {
    /// Canonical path of the built viewer.
    dist: PathBuf,
    /// Example worlds: file name and path, sorted by name.
    examples: Vec<(String, PathBuf)>,
    /// The world given on the command line.
    world: Option<GivenWorld>,
}

/// The world or scene given on the command line.
struct GivenWorld {
    /// Its file name.
    name: String,
    bytes: Vec<u8>,
    /// Whether it is one of the examples' files (the page then lists it as that example, not
    /// as the user's own file, which may have an example's name).
    is_example: bool,
}

/// The source tree this binary was built from (crates/jello-cli/../..).
fn source_tree() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Serves the viewer until the process is stopped.
pub fn view(args: ViewArgs) -> Result<(), CliError> {
    let dist = args
        .dist
        .clone()
        .unwrap_or_else(|| source_tree().join("web/dist"));
    if !dist.join("index.html").is_file() {
        return Err(CliError::input(format!(
            "the viewer is not built: {} is missing; run `make web` (or `scripts/web.sh build`) first, or pass --dist DIR",
            dist.join("index.html").display()
        )));
    }
    let dist = dist
        .canonicalize()
        .map_err(|e| CliError::input(format!("{}: {e}", dist.display())))?;
    let examples = list_examples(&source_tree().join("examples"));
    let world = match &args.world {
        Some(path) => {
            // Check it now, so a bad file is reported here with its line, not in the browser.
            load(path, None, None)?;
            let bytes = fs::read(path)
                .map_err(|e| CliError::input(format!("{}: cannot read: {e}", path.display())))?;
            let name = path
                .file_name()
                .map_or_else(|| "world.w".into(), |n| n.to_string_lossy().into_owned());
            let is_example = is_one_of(path, &examples);
            Some(GivenWorld {
                name,
                bytes,
                is_example,
            })
        }
        None => None,
    };

    let addr = SocketAddrV4::new(Ipv4Addr::LOCALHOST, args.port);
    let listener = TcpListener::bind(addr)
        .map_err(|e| CliError::input(format!("cannot listen on {addr}: {e}")))?;
    let port = listener.local_addr().map(|a| a.port()).unwrap_or(args.port);
    let url = format!("http://127.0.0.1:{port}/");
    let showing = match &world {
        Some(given) => given.name.clone(),
        None if examples.iter().any(|(n, _)| n == "jello.w") => "examples/jello.w".into(),
        None => "the classic cube".into(),
    };
    println!("Jello viewer at {url} showing {showing} (Ctrl-C stops it)");
    let _ = io::stdout().flush();
    if args.open {
        open_browser(&url);
    }

    let site = Arc::new(Site {
        dist,
        examples,
        world,
    });
    let open_connections = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        if open_connections.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            open_connections.fetch_sub(1, Ordering::SeqCst);
            let _ = respond(
                &stream,
                false,
                503,
                "text/plain; charset=utf-8",
                b"busy\n",
                &[],
            );
            continue;
        }
        let (site, open_connections) = (Arc::clone(&site), Arc::clone(&open_connections));
        thread::spawn(move || {
            // A client that hangs up mid-response is not our error.
            let _ = serve(&site, stream);
            open_connections.fetch_sub(1, Ordering::SeqCst);
        });
    }
    Ok(())
}

/// The `*.w` and `*.toml` files of `dir`, sorted by name; none when the folder is missing.
fn list_examples(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut found: Vec<(String, PathBuf)> = fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let name = entry.file_name().into_string().ok()?;
            let known = name.ends_with(".w") || name.ends_with(".toml");
            (known && entry.path().is_file()).then(|| (name, entry.path()))
        })
        .collect();
    found.sort();
    found
}

/// Whether `path` is the same file as one of `examples` (compared canonically, so
/// `./examples/jello.w` is the example and another folder's `jello.w` is not).
fn is_one_of(path: &Path, examples: &[(String, PathBuf)]) -> bool {
    let Ok(path) = path.canonicalize() else {
        return false;
    };
    examples
        .iter()
        .any(|(_, example)| example.canonicalize().is_ok_and(|e| e == path))
}

/// Tries `xdg-open URL`, saying so when it cannot.
fn open_browser(url: &str) {
    let result = Command::new("xdg-open")
        .arg(url)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn();
    match result {
        Ok(_) => println!("Asked xdg-open to open {url}"),
        Err(e) => println!("Could not open a browser (xdg-open: {e}); open {url} yourself"),
    }
}

/// Reads one request and answers it.
fn serve(site: &Site, mut stream: TcpStream) -> io::Result<()> {
    stream.set_read_timeout(Some(READ_TIMEOUT))?;
    let Some(head) = read_head(&mut stream)? else {
        return respond(
            &stream,
            false,
            400,
            "text/plain; charset=utf-8",
            b"bad request\n",
            &[],
        );
    };
    let mut parts = head.lines().next().unwrap_or("").split(' ');
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let head_only = method == "HEAD";
    if method != "GET" && !head_only {
        return respond(
            &stream,
            false,
            405,
            "text/plain; charset=utf-8",
            b"only GET and HEAD\n",
            &[("Allow", "GET, HEAD")],
        );
    }
    match resolve(site, target) {
        Some((content_type, body)) => respond(&stream, head_only, 200, content_type, &body, &[]),
        None => respond(
            &stream,
            head_only,
            404,
            "text/plain; charset=utf-8",
            b"not found\n",
            &[],
        ),
    }
}

/// The request head (up to the blank line) as text; `None` when it is too long, not UTF-8 or
/// cut short.
fn read_head(stream: &mut TcpStream) -> io::Result<Option<String>> {
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 2048];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf)?;
        if n == 0 || head.len() + n > MAX_REQUEST_HEAD {
            return Ok(None);
        }
        head.extend_from_slice(&buf[..n]);
    }
    Ok(String::from_utf8(head).ok())
}

/// The content type and bytes for a request target, or `None` for "not found".
fn resolve(site: &Site, target: &str) -> Option<(&'static str, Vec<u8>)> {
    let path = target.split(['?', '#']).next()?;
    let path = percent_decode(path)?;
    let path = path.strip_prefix('/')?;
    match path {
        "" => return file(&site.dist.join("index.html")),
        "config.json" => return Some((content_type("json"), config_json(site).into_bytes())),
        "world.w" => {
            let given = site.world.as_ref()?;
            return Some((content_type("w"), given.bytes.clone()));
        }
        _ => {}
    }
    if let Some(name) = path.strip_prefix("examples/") {
        let (_, file_path) = site.examples.iter().find(|(n, _)| n == name)?;
        return file(file_path);
    }
    // A file of the built viewer: every segment a plain name, and the result inside dist.
    let mut full = site.dist.clone();
    for segment in path.split('/') {
        let plain = !segment.is_empty()
            && !segment.starts_with('.')
            && !segment.contains(['\\', '\0', ':']);
        if !plain {
            return None;
        }
        full.push(segment);
    }
    let full = full.canonicalize().ok()?;
    if !full.starts_with(&site.dist) {
        return None;
    }
    file(&full)
}

/// A regular file's content type (by extension) and bytes.
fn file(path: &Path) -> Option<(&'static str, Vec<u8>)> {
    if !path.is_file() {
        return None;
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    Some((content_type(ext), fs::read(path).ok()?))
}

fn content_type(ext: &str) -> &'static str {
    match ext.to_ascii_lowercase().as_str() {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "wasm" => "application/wasm",
        "json" | "map" => "application/json",
        "png" => "image/png",
        "svg" => "image/svg+xml",
        "ico" => "image/x-icon",
        "w" | "txt" | "toml" => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

/// What the page asks first: the world to start with and the examples to list.
fn config_json(site: &Site) -> String {
    let world = match &site.world {
        Some(given) => format!(
            r#"{{"url": "world.w", "name": {}, "example": {}}}"#,
            json_string(&given.name),
            given.is_example
        ),
        None => "null".into(),
    };
    let examples: Vec<String> = site.examples.iter().map(|(n, _)| json_string(n)).collect();
    format!(
        r#"{{"world": {world}, "examples": [{}]}}"#,
        examples.join(", ")
    )
}

/// `s` as a JSON string literal.
fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Decodes `%XX` escapes; `None` for a malformed escape or bytes that are not UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

fn respond(
    stream: &TcpStream,
    head_only: bool,
    status: u16,
    content_type: &str,
    body: &[u8],
    extra: &[(&str, &str)],
) -> io::Result<()> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        _ => "Service Unavailable",
    };
    let mut w = BufWriter::new(stream);
    write!(
        w,
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\n\
         Cache-Control: no-cache\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n",
        body.len()
    )?;
    for (name, value) in extra {
        write!(w, "{name}: {value}\r\n")?;
    }
    w.write_all(b"\r\n")?;
    if !head_only {
        w.write_all(body)?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("/a%20b").as_deref(), Some("/a b"));
        assert_eq!(percent_decode("/%2e%2e/x").as_deref(), Some("/../x"));
        assert_eq!(percent_decode("/%zz"), None);
        assert_eq!(percent_decode("/%2"), None);
        assert_eq!(percent_decode("/%ff"), None);
    }

    #[test]
    fn json_strings_are_escaped() {
        assert_eq!(json_string(r#"a"b\c"#), r#""a\"b\\c""#);
        assert_eq!(json_string("x\ny"), r#""x\u000ay""#);
    }
}
