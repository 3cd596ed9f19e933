//! The sections both versions share: `$MeshFormat` (version, ASCII or binary, byte order)
//! and `$PhysicalNames`.

use super::cursor::{parse_tok, show, show_hex, Cursor};
use super::GmshError;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Version {
    V22,
    V41,
}

#[derive(Debug)]
pub(super) struct MeshFormat {
    pub(super) version: Version,
    pub(super) binary: bool,
    /// Size of `size_t` (4.1) or of a double (2.2), in bytes.
    pub(super) data_size: usize,
    /// Offset of the `$MeshFormat` line, where the file proper starts.
    pub(super) start: usize,
}

pub(super) fn parse_mesh_format(cur: &mut Cursor<'_>) -> Result<MeshFormat, GmshError> {
    const SEC: &str = "$MeshFormat";
    cur.skip_ws();
    let start = cur.pos;
    let (line, at) = cur.line().ok_or(GmshError::MissingSection {
        section: SEC.to_string(),
    })?;
    if line.trim_ascii() != SEC.as_bytes() {
        return Err(cur.err(
            at,
            show(line),
            "\"$MeshFormat\" (a Gmsh .msh file starts with it)",
        ));
    }
    let (line, at) = cur.section_line(SEC, "\"version file-type data-size\"")?;
    let toks: Vec<&[u8]> = line
        .split(u8::is_ascii_whitespace)
        .filter(|t| !t.is_empty())
        .collect();
    if toks.len() != 3 {
        return Err(cur.err(
            at,
            show(line),
            "three numbers \"version file-type data-size\"",
        ));
    }
    let version = match parse_tok::<f64>(toks[0]) {
        Some(2.2) => Version::V22,
        Some(4.1) => Version::V41,
        Some(_) => {
            return Err(GmshError::UnsupportedVersion {
                found: String::from_utf8_lossy(toks[0]).into_owned(),
            })
        }
        None => return Err(cur.err(at, show(toks[0]), "a version number such as 2.2 or 4.1")),
    };
    let binary = match toks[1] {
        b"0" => false,
        b"1" => true,
        other => return Err(cur.err(at, show(other), "file-type 0 (ASCII) or 1 (binary)")),
    };
    let data_size: usize = parse_tok(toks[2]).unwrap_or(0);
    let ok_size = match version {
        // 2.2: size of a double; 4.1: size of size_t (mshio reads 4 or 8).
        Version::V22 => data_size == 8,
        Version::V41 => data_size == 8 || data_size == 4,
    };
    if !ok_size {
        let expected = match version {
            Version::V22 => "data-size 8",
            Version::V41 => "data-size 4 or 8",
        };
        return Err(cur.err(at, show(toks[2]), expected));
    }
    if binary {
        // A binary header carries the int 1 in the writer's byte order.
        let at = cur.pos;
        let one = cur
            .take(4)
            .ok_or_else(|| cur.truncated(SEC, "the binary integer 1 after the header line"))?;
        let mut a = [0u8; 4];
        a.copy_from_slice(one);
        if i32::from_le_bytes(a) == 1 {
            cur.little_endian = true;
        } else if i32::from_be_bytes(a) == 1 {
            cur.little_endian = false;
        } else {
            return Err(GmshError::Binary {
                offset: at,
                found: show_hex(one),
                expected: "the binary integer 1 (byte-order mark) after \"... 1 8\"".into(),
            });
        }
    }
    cur.expect_end("MeshFormat")?;
    Ok(MeshFormat {
        version,
        binary,
        data_size,
        start,
    })
}

/// `$PhysicalNames` content (ASCII in every variant): `n`, then `dim tag "name"` lines.
pub(super) fn parse_physical_names(
    cur: &mut Cursor<'_>,
) -> Result<Vec<(i32, i32, String)>, GmshError> {
    const SEC: &str = "$PhysicalNames";
    // This section is text even in binary files, so report lines.
    let binary = std::mem::replace(&mut cur.binary, false);
    let result = (|| {
        let (line, at) = cur.section_line(SEC, "the number of physical names")?;
        let n: usize = parse_tok(line)
            .ok_or_else(|| cur.err(at, show(line), "the number of physical names"))?;
        let mut names = Vec::new();
        for _ in 0..n {
            let (line, at) = cur.section_line(SEC, "a line \"dim tag \\\"name\\\"\"")?;
            let bad = || cur.err(at, show(line), "\"dim tag \\\"name\\\"\"");
            let mut rest = line;
            let mut nums = [0i32; 2];
            for v in &mut nums {
                let t = rest.trim_ascii_start();
                let end = t
                    .iter()
                    .position(u8::is_ascii_whitespace)
                    .unwrap_or(t.len());
                *v = parse_tok(&t[..end]).ok_or_else(bad)?;
                rest = &t[end..];
            }
            let name = rest.trim_ascii();
            let name = name
                .strip_prefix(b"\"")
                .and_then(|s| s.strip_suffix(b"\""))
                .ok_or_else(bad)?;
            names.push((nums[0], nums[1], String::from_utf8_lossy(name).into_owned()));
        }
        cur.expect_end("PhysicalNames")?;
        Ok(names)
    })();
    cur.binary = binary;
    result
}
