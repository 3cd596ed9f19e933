//! The low-level reader under both versions: a byte cursor that reports errors by line
//! (ASCII) or byte offset (binary), and the quoting of what was found.

use super::GmshError;

/// Quote at most 40 bytes of `b` for an error message.
pub(super) fn show(b: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(&b[..b.len().min(MAX)]);
    if b.len() > MAX {
        format!("{text:?}...")
    } else {
        format!("{text:?}")
    }
}

/// Hex dump of at most 8 bytes, for binary error messages.
pub(super) fn show_hex(b: &[u8]) -> String {
    if b.is_empty() {
        return "end of data".to_string();
    }
    let hex: Vec<String> = b.iter().take(8).map(|x| format!("{x:02x}")).collect();
    format!("bytes [{}]", hex.join(" "))
}

/// A position in the input plus the knowledge of how to report errors there.
#[derive(Clone)]
pub(super) struct Cursor<'a> {
    pub(super) b: &'a [u8],
    pub(super) pos: usize,
    /// Report positions as byte offsets (binary files) rather than line numbers.
    pub(super) binary: bool,
    pub(super) little_endian: bool,
}

impl<'a> Cursor<'a> {
    pub(super) fn new(b: &'a [u8]) -> Self {
        Self {
            b,
            pos: 0,
            binary: false,
            little_endian: true,
        }
    }

    pub(super) fn eof(&self) -> bool {
        self.pos >= self.b.len()
    }

    /// 1-based line number of byte `pos` (computed only for error messages).
    pub(super) fn line_of(&self, pos: usize) -> usize {
        1 + self.b[..pos.min(self.b.len())]
            .iter()
            .filter(|&&c| c == b'\n')
            .count()
    }

    /// Error at byte `pos`, located by line (ASCII) or offset (binary).
    pub(super) fn err(&self, pos: usize, found: String, expected: impl Into<String>) -> GmshError {
        if self.binary {
            GmshError::Binary {
                offset: pos,
                found,
                expected: expected.into(),
            }
        } else {
            GmshError::Parse {
                line: self.line_of(pos),
                found,
                expected: expected.into(),
            }
        }
    }

    pub(super) fn truncated(&self, section: &str, expected: impl Into<String>) -> GmshError {
        GmshError::Truncated {
            section: section.to_string(),
            offset: self.b.len(),
            expected: expected.into(),
        }
    }

    pub(super) fn skip_ws(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// The rest of the current line without its terminator, and where it starts.
    pub(super) fn line(&mut self) -> Option<(&'a [u8], usize)> {
        if self.eof() {
            return None;
        }
        let start = self.pos;
        let rest = &self.b[start..];
        let len = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos = (start + len + 1).min(self.b.len());
        let mut line = &rest[..len];
        if let Some(stripped) = line.strip_suffix(b"\r") {
            line = stripped;
        }
        Some((line, start))
    }

    /// The next non-empty line of a section (trimmed), or a truncation error.
    pub(super) fn section_line(
        &mut self,
        section: &str,
        expected: &str,
    ) -> Result<(&'a [u8], usize), GmshError> {
        loop {
            match self.line() {
                None => return Err(self.truncated(section, expected)),
                Some((l, start)) => {
                    let t = l.trim_ascii();
                    if !t.is_empty() {
                        let offset = l.len() - l.trim_ascii_start().len();
                        return Ok((t, start + offset));
                    }
                }
            }
        }
    }

    /// Next whitespace-separated token regardless of lines, and where it starts.
    pub(super) fn token(&mut self) -> Option<(&'a [u8], usize)> {
        self.skip_ws();
        if self.eof() {
            return None;
        }
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Some((&self.b[start..self.pos], start))
    }

    /// `n` raw bytes, or `None` if fewer remain.
    pub(super) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.b.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }

    pub(super) fn i32_at(&self, b: &[u8]) -> i32 {
        let mut a = [0u8; 4];
        a.copy_from_slice(&b[..4]);
        if self.little_endian {
            i32::from_le_bytes(a)
        } else {
            i32::from_be_bytes(a)
        }
    }

    pub(super) fn f64_at(&self, b: &[u8]) -> f64 {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        if self.little_endian {
            f64::from_le_bytes(a)
        } else {
            f64::from_be_bytes(a)
        }
    }

    /// Unsigned integer of `size` bytes (4 or 8) in the file's byte order.
    pub(super) fn uint_at(&self, b: &[u8], size: usize) -> u64 {
        let mut v = 0u64;
        for i in 0..size {
            let byte = if self.little_endian {
                b[size - 1 - i]
            } else {
                b[i]
            };
            v = (v << 8) | u64::from(byte);
        }
        v
    }

    /// Expect the line `$End<name>` (after optional whitespace).
    pub(super) fn expect_end(&mut self, name: &str) -> Result<(), GmshError> {
        let end = format!("$End{name}");
        let section = format!("${name}");
        self.skip_ws();
        let (line, start) = self
            .line()
            .ok_or_else(|| self.truncated(&section, format!("\"{end}\"")))?;
        if line.trim_ascii() != end.as_bytes() {
            return Err(self.err(start, show(line), format!("\"{end}\" closing {section}")));
        }
        Ok(())
    }

    /// Skip an unparsed section: move past the line `$End<name>`.
    pub(super) fn skip_section(&mut self, name: &str) -> Result<(), GmshError> {
        let end = format!("$End{name}");
        let pat = end.as_bytes();
        let mut from = self.pos;
        while let Some(i) = find(&self.b[from..], pat) {
            let at = from + i;
            let after = at + pat.len();
            // Only a whole line counts, so that "$EndNodes" does not match "$EndNodesX".
            let starts_line = at == 0 || self.b[at - 1] == b'\n';
            let ends_line = after == self.b.len() || self.b[after].is_ascii_whitespace();
            if starts_line && ends_line {
                self.pos = after;
                // Consume the rest of the line.
                self.line();
                return Ok(());
            }
            from = at + 1;
        }
        Err(self.truncated(&format!("${name}"), format!("\"{end}\"")))
    }

    /// Next section header `$Name`: `Ok(None)` at end of input.
    pub(super) fn next_section(&mut self) -> Result<Option<(String, usize)>, GmshError> {
        self.skip_ws();
        let Some((line, start)) = self.line() else {
            return Ok(None);
        };
        let t = line.trim_ascii();
        match t.strip_prefix(b"$") {
            Some(name) if !name.is_empty() && name.iter().all(u8::is_ascii_alphanumeric) => {
                Ok(Some((String::from_utf8_lossy(name).into_owned(), start)))
            }
            _ => Err(self.err(
                start,
                show(t),
                "a section header such as \"$Nodes\" or \"$Elements\"",
            )),
        }
    }
}

/// Position of `needle` in `hay` (naive; section end tags are short).
pub(super) fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() || hay.len() < needle.len() {
        return None;
    }
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Parse a whole ASCII token as `T`.
pub(super) fn parse_tok<T: std::str::FromStr>(tok: &[u8]) -> Option<T> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}
