//! What the text readers (OBJ and ASCII STL) share: the check that the bytes are text, and
//! numbers.

use crate::formats::world::{is_space, show};

/// The UTF-8 byte-order mark, which some Windows tools write first.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// The bytes without a leading byte-order mark.
pub(super) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(BOM).unwrap_or(bytes)
}

/// The 1-based line holding byte `at`.
pub(super) fn line_of(bytes: &[u8], at: usize) -> usize {
    1 + bytes[..at].iter().filter(|&&b| b == b'\n').count()
}

/// Where and why bytes are not text.
pub(super) struct NotText {
    /// Offset of the first offending byte.
    pub(super) at: usize,
    /// Its 1-based line.
    pub(super) line: usize,
    /// What it is.
    pub(super) message: String,
}

/// Checks that `bytes` are UTF-8 text: no invalid sequence and no control character other than
/// white space.
pub(super) fn check_text(bytes: &[u8]) -> Result<&str, NotText> {
    // Multi-byte UTF-8 sequences hold no byte below 0x80, so control bytes can be found in the
    // raw bytes.
    let control = bytes
        .iter()
        .position(|&b| (b < 0x20 && !is_space(b)) || b == 0x7f);
    let utf8 = std::str::from_utf8(bytes);
    let bad = match &utf8 {
        Ok(_) => bytes.len(),
        Err(e) => e.valid_up_to(),
    };
    if let Some(at) = control.filter(|&at| at < bad) {
        return Err(NotText {
            at,
            line: line_of(bytes, at),
            message: format!(
                "the file is not text: control character 0x{:02x}",
                bytes[at]
            ),
        });
    }
    utf8.map_err(|e| {
        let len = e.error_len().unwrap_or(bytes.len() - bad).min(4);
        NotText {
            at: bad,
            line: line_of(bytes, bad),
            message: format!(
                "the file is not UTF-8 text: invalid byte sequence {}",
                show(&bytes[bad..bad + len])
            ),
        }
    })
}

/// A token read as a number (of any value, NaN and infinities included), or `None`.
pub(super) fn number(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse::<f64>().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_offence_is_found_with_its_line() {
        assert_eq!(
            check_text(b"v 1\r\n\tv\x0b\x0c2\n").ok(),
            Some("v 1\r\n\tv\x0b\x0c2\n")
        );
        assert_eq!(check_text("é ☃\n".as_bytes()).ok(), Some("é ☃\n"));
        for (bytes, at, line, needle) in [
            (&b"a\nb\n\xff"[..], 4, 3, "\"\\xff\""),
            (b"a\n\0\n\xff", 2, 2, "0x00"),
            (b"a\n\xff\n\0", 2, 2, "UTF-8"),
            (b"\n\n\x7f", 2, 3, "0x7f"),
            (b"\xe2\x98", 0, 1, "\"\\xe2\\x98\""),
        ] {
            let e = check_text(bytes).err().unwrap();
            assert_eq!((e.at, e.line), (at, line), "{}", e.message);
            assert!(e.message.contains(needle), "{}", e.message);
        }
    }

    #[test]
    fn lines_count_from_one() {
        assert_eq!(line_of(b"", 0), 1);
        assert_eq!(line_of(b"a\nb\nc", 4), 3);
        assert_eq!(strip_bom(b"\xef\xbb\xbfx"), b"x");
        assert_eq!(strip_bom(b"\xef\xbbx"), b"\xef\xbbx");
    }
}
