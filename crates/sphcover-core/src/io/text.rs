//! Byte-level helpers shared by the text formats: a line cursor that counts lines, a
//! tokenizer that never allocates, number parsing and shortest round-trip number printing.
//!
//! Text formats are parsed straight from the file's bytes rather than through `String`
//! lines: it avoids one allocation per line and keeps invalid UTF-8 a per-token problem
//! (reported with its line) instead of a whole-file one.

use super::error::{Failure, Location, Problem, token_for_message};

/// Walks a byte buffer line by line, counting lines from 1.
#[derive(Debug)]
pub(crate) struct LineCursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: u64,
}

impl<'a> LineCursor<'a> {
    /// A cursor at byte `pos`, which is the start of line `line` (1-based).
    pub(crate) fn new(bytes: &'a [u8], pos: usize, line: u64) -> LineCursor<'a> {
        LineCursor {
            bytes,
            pos: pos.min(bytes.len()),
            line: line.saturating_sub(1),
        }
    }

    /// The next line without its terminator (`\n`, `\r\n` or a lone `\r` before `\n`), and
    /// its 1-based number.
    #[inline]
    pub(crate) fn next_line(&mut self) -> Option<(u64, &'a [u8])> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let (mut line, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(n) => (&rest[..n], n + 1),
            None => (rest, rest.len()),
        };
        if let [head @ .., b'\r'] = line {
            line = head;
        }
        self.pos += advance;
        self.line += 1;
        Some((self.line, line))
    }

    /// The next line holding something other than blanks and (when `comment` is given)
    /// a comment introduced by that byte. The comment part is cut off the returned line.
    #[inline]
    pub(crate) fn next_content_line(&mut self, comment: Option<u8>) -> Option<(u64, &'a [u8])> {
        while let Some((n, line)) = self.next_line() {
            let line = match comment {
                Some(c) => match line.iter().position(|&b| b == c) {
                    Some(k) => &line[..k],
                    None => line,
                },
                None => line,
            };
            if line.iter().any(|&b| !is_blank(b)) {
                return Some((n, line));
            }
        }
        None
    }

    /// Number of the last line returned (0 before the first).
    pub(crate) fn line(&self) -> u64 {
        self.line
    }

    /// Number the next line will have.
    pub(crate) fn next_line_number(&self) -> u64 {
        self.line + 1
    }

    /// Byte offset of the start of the next line.
    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    /// Bytes not yet consumed.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

/// Blank bytes between tokens.
#[inline]
pub(crate) fn is_blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// Splits a line into tokens separated by blanks (and by commas when `commas`).
#[derive(Clone, Debug)]
pub(crate) struct Tokens<'a> {
    rest: &'a [u8],
    commas: bool,
}

impl<'a> Tokens<'a> {
    pub(crate) fn new(line: &'a [u8], commas: bool) -> Tokens<'a> {
        Tokens { rest: line, commas }
    }

    #[inline]
    fn is_separator(&self, b: u8) -> bool {
        is_blank(b) || (self.commas && b == b',')
    }
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a [u8];

    #[inline]
    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.rest.iter().position(|&b| !self.is_separator(b))?;
        let rest = &self.rest[start..];
        let end = rest
            .iter()
            .position(|&b| self.is_separator(b))
            .unwrap_or(rest.len());
        self.rest = &rest[end..];
        Some(&rest[..end])
    }
}

/// Parses a decimal floating-point token (`1`, `-2.5e3`, `nan`, `inf`, `-Infinity`).
#[inline]
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Parses a token as `f32`: the exact value a `float` field denotes, which parsing as `f64`
/// and rounding could miss by one unit in rare double-rounding cases.
#[inline]
pub(crate) fn parse_f32(token: &[u8]) -> Option<f32> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Parses an integer token; a float token with an integral value is accepted too, since some
/// writers print every number with a decimal point.
#[inline]
pub(crate) fn parse_integer(token: &[u8]) -> Option<i64> {
    let text = std::str::from_utf8(token).ok()?;
    if let Ok(v) = text.parse::<i64>() {
        return Some(v);
    }
    let v: f64 = text.parse().ok()?;
    // 2^63 itself does not fit i64; the comparison keeps the cast exact.
    if v.fract() == 0.0 && (-9.223_372_036_854_776e18..9.223_372_036_854_776e18).contains(&v) {
        Some(v as i64)
    } else {
        None
    }
}

/// The error for a token that is not a number.
pub(crate) fn bad_number(
    at: Location,
    element: &str,
    index: u64,
    token: &[u8],
    integer: bool,
) -> Failure {
    Failure::new(
        at,
        Problem::BadNumber {
            element: element.to_string(),
            index,
            token: token_for_message(token),
            expected: if integer {
                " (expected an integer)"
            } else {
                ""
            },
        },
    )
}

/// Appends the shortest decimal text that reads back as exactly `v`.
///
/// Rust's `Display` for floats prints the shortest round-trip digits but never uses an
/// exponent, which turns `1e300` into 301 characters; very large and very small magnitudes
/// therefore use the (equally exact) exponent form.
pub(crate) fn push_f64(out: &mut Vec<u8>, v: f64) {
    use std::io::Write;
    let a = v.abs();
    // Writing into a Vec cannot fail.
    let _ = if a != 0.0 && a.is_finite() && !(1e-5..1e16).contains(&a) {
        write!(out, "{v:e}")
    } else {
        write!(out, "{v}")
    };
}

/// Like [`push_f64`] for a value stored as `f32`: the shortest text that reads back as the
/// same `f32`.
pub(crate) fn push_f32(out: &mut Vec<u8>, v: f32) {
    use std::io::Write;
    let a = v.abs();
    let _ = if a != 0.0 && a.is_finite() && !(1e-5..1e16).contains(&a) {
        write!(out, "{v:e}")
    } else {
        write!(out, "{v}")
    };
}

/// Appends a number at the requested precision.
#[inline]
pub(crate) fn push_real(out: &mut Vec<u8>, v: f64, double: bool) {
    if double {
        push_f64(out, v)
    } else {
        push_f32(out, v as f32)
    }
}

/// Appends an unsigned integer.
#[inline]
pub(crate) fn push_uint(out: &mut Vec<u8>, v: u64) {
    use std::io::Write;
    let _ = write!(out, "{v}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_strip_crlf_and_count() {
        let mut c = LineCursor::new(b"a\r\n\nb # c\n  \nd", 0, 1);
        assert_eq!(c.next_line(), Some((1, &b"a"[..])));
        assert_eq!(c.next_content_line(Some(b'#')), Some((3, &b"b "[..])));
        assert_eq!(c.next_content_line(Some(b'#')), Some((5, &b"d"[..])));
        assert_eq!(c.next_line(), None);
    }

    #[test]
    fn tokens_split_on_blanks_and_commas() {
        let t: Vec<&[u8]> = Tokens::new(b" 1,2\t3 ,, 4 ", true).collect();
        assert_eq!(t, vec![&b"1"[..], b"2", b"3", b"4"]);
        let t: Vec<&[u8]> = Tokens::new(b"1,2 3", false).collect();
        assert_eq!(t, vec![&b"1,2"[..], b"3"]);
    }

    #[test]
    fn numbers_round_trip_through_text() {
        for v in [0.1, -0.0, 1e300, 5e-324, 123456.789, f64::MAX, 1.0 / 3.0] {
            let mut s = Vec::new();
            push_f64(&mut s, v);
            assert_eq!(parse_f64(&s).map(f64::to_bits), Some(v.to_bits()), "{v}");
        }
        for v in [0.1f32, 1e-40, f32::MAX, 7.0e12] {
            let mut s = Vec::new();
            push_f32(&mut s, v);
            assert_eq!(parse_f32(&s), Some(v));
        }
        assert!(parse_f64(b"nan").unwrap().is_nan());
        assert_eq!(parse_f64(b"-inf"), Some(f64::NEG_INFINITY));
        assert_eq!(parse_integer(b"3.0"), Some(3));
        assert_eq!(parse_integer(b"3.5"), None);
        assert_eq!(parse_integer(b"1e30"), None);
    }
}
