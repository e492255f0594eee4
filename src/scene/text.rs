//! Shared helpers for the text formats: a line cursor that counts lines, and number parsing
//! that reports what it found.

/// Iterates over the lines of a byte buffer, tracking 1-based line numbers and byte offsets.
pub(crate) struct Lines<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Lines<'a> {
    /// A cursor at the start of `data` (line 1).
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Lines {
            data,
            pos: 0,
            line: 0,
        }
    }

    /// The 1-based number of the line last returned by [`Lines::next_line`].
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// Byte offset of the start of the next line.
    pub(crate) fn offset(&self) -> usize {
        self.pos
    }

    /// The next line without its terminator (`\n` or `\r\n`), or `None` at the end.
    pub(crate) fn next_line(&mut self) -> Option<&'a [u8]> {
        if self.pos >= self.data.len() {
            return None;
        }
        let rest = &self.data[self.pos..];
        let (line, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        self.pos += advance;
        self.line += 1;
        Some(line.strip_suffix(b"\r").unwrap_or(line))
    }
}

/// Splits a line into tokens separated by ASCII whitespace (and commas when `commas` is set).
pub(crate) fn tokens(line: &[u8], commas: bool) -> impl Iterator<Item = &[u8]> {
    line.split(move |&b| {
        b == b' ' || b == b'\t' || b == b'\r' || b == 0x0c || (commas && b == b',')
    })
    .filter(|t| !t.is_empty())
}

/// Parses an ASCII floating-point number (also `nan`, `inf`).
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    if let Some(v) = parse_small_decimal(token) {
        return Some(v);
    }
    std::str::from_utf8(token).ok()?.parse::<f64>().ok()
}

/// Fast exact path for plain decimals with at most 15 significant digits and no exponent:
/// the mantissa and the power of ten are both exactly representable, so one division is
/// correctly rounded. Returns `None` for anything else (the caller falls back to `str::parse`).
fn parse_small_decimal(token: &[u8]) -> Option<f64> {
    let (negative, digits) = match token.first()? {
        b'-' => (true, &token[1..]),
        b'+' => (false, &token[1..]),
        _ => (false, token),
    };
    if digits.is_empty() || digits.len() > 16 {
        return None;
    }
    let mut mantissa: u64 = 0;
    let mut frac_digits: i32 = -1;
    let mut any_digit = false;
    for &b in digits {
        match b {
            b'0'..=b'9' => {
                mantissa = mantissa * 10 + u64::from(b - b'0');
                any_digit = true;
                if frac_digits >= 0 {
                    frac_digits += 1;
                }
            }
            b'.' if frac_digits < 0 => frac_digits = 0,
            _ => return None,
        }
    }
    if !any_digit {
        return None;
    }
    const POW10: [f64; 16] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
    ];
    let value = mantissa as f64 / POW10[frac_digits.max(0) as usize];
    Some(if negative { -value } else { value })
}

/// Parses an ASCII integer (optional sign), rejecting overflow.
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    let (negative, digits) = match token.first()? {
        b'-' => (true, &token[1..]),
        b'+' => (false, &token[1..]),
        _ => (false, token),
    };
    if digits.is_empty() {
        return None;
    }
    let mut value: i64 = 0;
    for &b in digits {
        if !b.is_ascii_digit() {
            return None;
        }
        value = value.checked_mul(10)?.checked_add(i64::from(b - b'0'))?;
    }
    Some(if negative { -value } else { value })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_decimal_matches_std() {
        for s in [
            "0",
            "-0.5",
            "1.0",
            "0.0527295",
            "-0.108324",
            "123456.789",
            "+3.",
            ".25",
        ] {
            let fast = parse_f64(s.as_bytes()).unwrap();
            let std: f64 = s.parse().unwrap();
            assert_eq!(fast, std, "{s}");
        }
        assert!(parse_f64(b"1e-3").unwrap() == 1e-3);
        assert!(parse_f64(b"nan").unwrap().is_nan());
        assert!(parse_f64(b"abc").is_none());
        assert!(parse_f64(b".").is_none());
        assert!(parse_f64(b"-").is_none());
    }

    #[test]
    fn integers_and_lines() {
        assert_eq!(parse_i64(b"-42"), Some(-42));
        assert_eq!(parse_i64(b"99999999999999999999"), None);
        let mut lines = Lines::new(b"a b \r\n\nc");
        assert_eq!(lines.next_line(), Some(&b"a b "[..]));
        assert_eq!(tokens(b"a b ", false).count(), 2);
        assert_eq!(lines.next_line(), Some(&b""[..]));
        assert_eq!(lines.next_line(), Some(&b"c"[..]));
        assert_eq!(lines.line(), 3);
        assert_eq!(lines.next_line(), None);
    }
}
