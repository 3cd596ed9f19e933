//! Reader for Gmsh `.msh` meshes: MSH 2.2 and 4.1, ASCII and binary.
//!
//! * 4.1 is parsed by the `mshio` crate; this module adds what `mshio` 0.4 leaves out
//!   (`$PhysicalNames`, node tags of contiguously numbered files) and guards against its panics.
//! * 2.2 (ASCII and binary) is parsed by hand here, since `mshio` only knows 4.1.
//!
//! Node tags in a file are arbitrary (sparse, unordered); [`GmshMesh::nodes`] holds the nodes
//! densely in file order and [`GmshElement::nodes`] indexes into it (0-based).
//!
//! Corrupt or truncated input gives a [`GmshError`], never a panic. Errors name what was found,
//! what was expected, and where (line for ASCII, byte offset for binary data).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Kind of a mesh element, after the Gmsh element type id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GmshCellKind {
    /// 1-node point (Gmsh type 15).
    Point1,
    /// 2-node line (Gmsh type 1).
    Line2,
    /// 3-node triangle (Gmsh type 2).
    Tri3,
    /// 4-node quadrangle (Gmsh type 3).
    Quad4,
    /// 4-node tetrahedron (Gmsh type 4).
    Tet4,
    /// 8-node hexahedron (Gmsh type 5).
    Hex8,
    /// Any other Gmsh element type, by its Gmsh type id (e.g. 9 for the 6-node triangle).
    Other(i32),
}

impl GmshCellKind {
    /// Kind for a Gmsh element type id.
    pub fn from_gmsh_type(id: i32) -> Self {
        match id {
            15 => Self::Point1,
            1 => Self::Line2,
            2 => Self::Tri3,
            3 => Self::Quad4,
            4 => Self::Tet4,
            5 => Self::Hex8,
            other => Self::Other(other),
        }
    }

    /// The Gmsh element type id of this kind.
    pub fn gmsh_type(self) -> i32 {
        match self {
            Self::Point1 => 15,
            Self::Line2 => 1,
            Self::Tri3 => 2,
            Self::Quad4 => 3,
            Self::Tet4 => 4,
            Self::Hex8 => 5,
            Self::Other(id) => id,
        }
    }

    /// Topological dimension (0 to 3), or `None` for a Gmsh type this reader does not know.
    pub fn dimension(self) -> Option<usize> {
        type_info(self.gmsh_type()).map(|(_, dim)| dim)
    }

    /// Number of nodes, or `None` for a Gmsh type this reader does not know.
    pub fn node_count(self) -> Option<usize> {
        type_info(self.gmsh_type()).map(|(nodes, _)| nodes)
    }
}

/// (node count, dimension) of the fixed-size Gmsh element types 1 to 31 (from the Gmsh manual).
fn type_info(id: i32) -> Option<(usize, usize)> {
    Some(match id {
        1 => (2, 1),
        2 => (3, 2),
        3 => (4, 2),
        4 => (4, 3),
        5 => (8, 3),
        6 => (6, 3),
        7 => (5, 3),
        8 => (3, 1),
        9 => (6, 2),
        10 => (9, 2),
        11 => (10, 3),
        12 => (27, 3),
        13 => (18, 3),
        14 => (14, 3),
        15 => (1, 0),
        16 => (8, 2),
        17 => (20, 3),
        18 => (15, 3),
        19 => (13, 3),
        20 => (9, 2),
        21 => (10, 2),
        22 => (12, 2),
        23 => (15, 2),
        24 => (15, 2),
        25 => (21, 2),
        26 => (4, 1),
        27 => (5, 1),
        28 => (6, 1),
        29 => (20, 3),
        30 => (35, 3),
        31 => (56, 3),
        _ => return None,
    })
}

/// One element of a [`GmshMesh`].
#[derive(Debug, Clone)]
pub struct GmshElement {
    /// Element kind.
    pub kind: GmshCellKind,
    /// 0-based indices into [`GmshMesh::nodes`], in Gmsh node order (which for the linear
    /// kinds is also the VTK order).
    pub nodes: Vec<usize>,
    /// Physical group tag. MSH 2.2: the element's first tag (0 means none). MSH 4.1: the first
    /// physical tag of the element's entity in `$Entities`. `None` when there is none.
    /// (An entity in several groups: 4.1 gives its first group; 2.2 files repeat such
    /// elements once per group, and they are kept as listed.)
    pub physical_tag: Option<i32>,
    /// Elementary (geometric entity) tag; 0 when a 2.2 file gives fewer than two tags.
    pub entity_tag: i32,
}

/// A mesh read from a Gmsh file.
#[derive(Debug, Clone, Default)]
pub struct GmshMesh {
    /// Node coordinates, densely in file order.
    pub nodes: Vec<[f64; 3]>,
    /// Elements in file order (all dimensions mixed: boundary elements come too).
    pub elements: Vec<GmshElement>,
    /// `$PhysicalNames`: (dimension, physical tag, name).
    pub physical_names: Vec<(i32, i32, String)>,
}

impl GmshMesh {
    /// Largest dimension among the elements of known kind (`None` when there are none).
    pub fn highest_dimension(&self) -> Option<usize> {
        self.elements
            .iter()
            .filter_map(|e| e.kind.dimension())
            .max()
    }

    /// `(dimension, tag)` of the physical group called `name`, if `$PhysicalNames` has it.
    pub fn physical_tag_by_name(&self, name: &str) -> Option<(i32, i32)> {
        self.physical_names
            .iter()
            .find(|(_, _, n)| n == name)
            .map(|&(dim, tag, _)| (dim, tag))
    }
}

/// Why a Gmsh file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum GmshError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// `$MeshFormat` names a version other than 2.2 or 4.1.
    #[error("unsupported MSH format version {found:?}: expected 2.2 or 4.1")]
    UnsupportedVersion {
        /// The version string in the file.
        found: String,
    },
    /// Bad text in an ASCII part of the file.
    #[error("line {line}: found {found}, expected {expected}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is there.
        found: String,
        /// What should be there.
        expected: String,
    },
    /// Bad data in a binary part of the file.
    #[error("byte offset {offset}: found {found}, expected {expected}")]
    Binary {
        /// 0-based byte offset into the file.
        offset: usize,
        /// What is there.
        found: String,
        /// What should be there.
        expected: String,
    },
    /// The file ends inside a section.
    #[error("{section} is truncated: the file ends at byte {offset}, expected {expected}")]
    Truncated {
        /// The section, e.g. `$Nodes`.
        section: String,
        /// Where the data ran out (the file length).
        offset: usize,
        /// What was still expected.
        expected: String,
    },
    /// An element refers to a node tag that `$Nodes` does not define.
    #[error("element {element} refers to node tag {tag}, which no node in $Nodes has")]
    UnknownNodeTag {
        /// The missing node tag.
        tag: usize,
        /// The element's tag in the file.
        element: usize,
    },
    /// Two nodes have the same tag.
    #[error("node tag {tag} is defined twice, expected unique node tags")]
    DuplicateNodeTag {
        /// The repeated tag.
        tag: usize,
    },
    /// A required section is absent.
    #[error("no {section} section found, expected one")]
    MissingSection {
        /// The section, e.g. `$Elements`.
        section: String,
    },
    /// Inconsistent content whose position is not known.
    #[error("found {found}, expected {expected}")]
    Invalid {
        /// What is there.
        found: String,
        /// What should be there.
        expected: String,
    },
    /// The 4.1 parser (`mshio`) panicked on this input; caught so that callers get an error.
    #[error("the MSH 4.1 parser (mshio) failed on this input: {message}")]
    ParserPanic {
        /// The panic message.
        message: String,
    },
}

/// Read a Gmsh `.msh` file (2.2 or 4.1, ASCII or binary).
pub fn read_gmsh(path: &Path) -> Result<GmshMesh, GmshError> {
    let bytes = std::fs::read(path).map_err(|source| GmshError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_gmsh(&bytes)
}

/// Parse the bytes of a Gmsh `.msh` file (2.2 or 4.1, ASCII or binary).
pub fn parse_gmsh(bytes: &[u8]) -> Result<GmshMesh, GmshError> {
    let mut cur = Cursor::new(bytes);
    let header = parse_mesh_format(&mut cur)?;
    // Errors in the body of a binary file are located by byte offset, not line.
    cur.binary = header.binary;
    match header.version {
        Version::V22 => parse_v22(cur, &header),
        Version::V41 => parse_v41(cur, &header),
    }
}

// ---------------------------------------------------------------------------------------------
// Low-level reading
// ---------------------------------------------------------------------------------------------

/// Quote at most 40 bytes of `b` for an error message.
fn show(b: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(&b[..b.len().min(MAX)]);
    if b.len() > MAX {
        format!("{text:?}...")
    } else {
        format!("{text:?}")
    }
}

/// Hex dump of at most 8 bytes, for binary error messages.
fn show_hex(b: &[u8]) -> String {
    if b.is_empty() {
        return "end of data".to_string();
    }
    let hex: Vec<String> = b.iter().take(8).map(|x| format!("{x:02x}")).collect();
    format!("bytes [{}]", hex.join(" "))
}

/// A position in the input plus the knowledge of how to report errors there.
#[derive(Clone)]
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    /// Report positions as byte offsets (binary files) rather than line numbers.
    binary: bool,
    little_endian: bool,
}

impl<'a> Cursor<'a> {
    fn new(b: &'a [u8]) -> Self {
        Self {
            b,
            pos: 0,
            binary: false,
            little_endian: true,
        }
    }

    fn eof(&self) -> bool {
        self.pos >= self.b.len()
    }

    /// 1-based line number of byte `pos` (computed only for error messages).
    fn line_of(&self, pos: usize) -> usize {
        1 + self.b[..pos.min(self.b.len())]
            .iter()
            .filter(|&&c| c == b'\n')
            .count()
    }

    /// Error at byte `pos`, located by line (ASCII) or offset (binary).
    fn err(&self, pos: usize, found: String, expected: impl Into<String>) -> GmshError {
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

    fn truncated(&self, section: &str, expected: impl Into<String>) -> GmshError {
        GmshError::Truncated {
            section: section.to_string(),
            offset: self.b.len(),
            expected: expected.into(),
        }
    }

    fn skip_ws(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// The rest of the current line without its terminator, and where it starts.
    fn line(&mut self) -> Option<(&'a [u8], usize)> {
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
    fn section_line(
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
    fn token(&mut self) -> Option<(&'a [u8], usize)> {
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
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.b.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }

    fn i32_at(&self, b: &[u8]) -> i32 {
        let mut a = [0u8; 4];
        a.copy_from_slice(&b[..4]);
        if self.little_endian {
            i32::from_le_bytes(a)
        } else {
            i32::from_be_bytes(a)
        }
    }

    fn f64_at(&self, b: &[u8]) -> f64 {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        if self.little_endian {
            f64::from_le_bytes(a)
        } else {
            f64::from_be_bytes(a)
        }
    }

    /// Unsigned integer of `size` bytes (4 or 8) in the file's byte order.
    fn uint_at(&self, b: &[u8], size: usize) -> u64 {
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
    fn expect_end(&mut self, name: &str) -> Result<(), GmshError> {
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
    fn skip_section(&mut self, name: &str) -> Result<(), GmshError> {
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
    fn next_section(&mut self) -> Result<Option<(String, usize)>, GmshError> {
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
fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() || hay.len() < needle.len() {
        return None;
    }
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Parse a whole ASCII token as `T`.
fn parse_tok<T: std::str::FromStr>(tok: &[u8]) -> Option<T> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

// ---------------------------------------------------------------------------------------------
// $MeshFormat and $PhysicalNames (shared by both versions)
// ---------------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Version {
    V22,
    V41,
}

#[derive(Debug)]
struct MeshFormat {
    version: Version,
    binary: bool,
    /// Size of `size_t` (4.1) or of a double (2.2), in bytes.
    data_size: usize,
    /// Offset of the `$MeshFormat` line, where the file proper starts.
    start: usize,
}

fn parse_mesh_format(cur: &mut Cursor<'_>) -> Result<MeshFormat, GmshError> {
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
fn parse_physical_names(cur: &mut Cursor<'_>) -> Result<Vec<(i32, i32, String)>, GmshError> {
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

// ---------------------------------------------------------------------------------------------
// MSH 2.2
// ---------------------------------------------------------------------------------------------

fn parse_v22(mut cur: Cursor<'_>, header: &MeshFormat) -> Result<GmshMesh, GmshError> {
    let mut mesh = GmshMesh::default();
    let mut tag_to_index: Option<HashMap<usize, usize>> = None;
    let mut seen_elements = false;
    while let Some((name, at)) = cur.next_section()? {
        match name.as_str() {
            "PhysicalNames" => mesh.physical_names.extend(parse_physical_names(&mut cur)?),
            "Nodes" => {
                if tag_to_index.is_some() {
                    return Err(cur.err(at, show(b"$Nodes"), "a single $Nodes section"));
                }
                let (nodes, map) = if header.binary {
                    v22_nodes_binary(&mut cur)?
                } else {
                    v22_nodes_ascii(&mut cur)?
                };
                mesh.nodes = nodes;
                tag_to_index = Some(map);
                cur.expect_end("Nodes")?;
            }
            "Elements" => {
                let map = tag_to_index
                    .as_ref()
                    .ok_or_else(|| cur.err(at, show(b"$Elements"), "$Nodes before $Elements"))?;
                if seen_elements {
                    return Err(cur.err(at, show(b"$Elements"), "a single $Elements section"));
                }
                seen_elements = true;
                mesh.elements = if header.binary {
                    v22_elements_binary(&mut cur, map)?
                } else {
                    v22_elements_ascii(&mut cur, map)?
                };
                cur.expect_end("Elements")?;
            }
            // $NodeData, $Periodic, $Comments, ...: not needed for the geometry.
            other => cur.skip_section(other)?,
        }
    }
    if tag_to_index.is_none() {
        return Err(GmshError::MissingSection {
            section: "$Nodes".into(),
        });
    }
    if !seen_elements {
        return Err(GmshError::MissingSection {
            section: "$Elements".into(),
        });
    }
    Ok(mesh)
}

/// The count line that opens `$Nodes` / `$Elements`.
fn count_line(cur: &mut Cursor<'_>, section: &str, what: &str) -> Result<usize, GmshError> {
    // The count is ASCII even in binary files.
    let (line, at) = cur.section_line(section, what)?;
    parse_tok(line).ok_or_else(|| GmshError::Parse {
        line: cur.line_of(at),
        found: show(line),
        expected: what.to_string(),
    })
}

/// Record a node; a tag seen before is an error.
fn insert_node(map: &mut HashMap<usize, usize>, tag: usize, index: usize) -> Result<(), GmshError> {
    if map.insert(tag, index).is_some() {
        return Err(GmshError::DuplicateNodeTag { tag });
    }
    Ok(())
}

/// Capacity hint bounded by the input size, so a corrupt count cannot trigger a huge allocation.
fn capacity(count: usize, remaining: usize, min_record: usize) -> usize {
    count.min(remaining / min_record.max(1))
}

type NodesAndMap = (Vec<[f64; 3]>, HashMap<usize, usize>);

fn v22_nodes_ascii(cur: &mut Cursor<'_>) -> Result<NodesAndMap, GmshError> {
    const SEC: &str = "$Nodes";
    let n = count_line(cur, SEC, "the number of nodes")?;
    let cap = capacity(n, cur.b.len() - cur.pos, 8);
    let mut nodes = Vec::with_capacity(cap);
    let mut map = HashMap::with_capacity(cap);
    for i in 0..n {
        let expected = "a node line \"tag x y z\"";
        let (line, at) = cur.section_line(SEC, "the remaining node lines")?;
        let toks: Vec<&[u8]> = line
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty())
            .collect();
        if toks.len() != 4 {
            return Err(cur.err(at, show(line), expected));
        }
        let tag: usize = parse_tok(toks[0])
            .ok_or_else(|| cur.err(at, show(toks[0]), "a non-negative integer node tag"))?;
        let mut x = [0.0; 3];
        for (k, t) in toks[1..].iter().enumerate() {
            x[k] = parse_tok::<f64>(t)
                .filter(|v| v.is_finite())
                .ok_or_else(|| cur.err(at, show(t), "a finite coordinate"))?;
        }
        insert_node(&mut map, tag, i)?;
        nodes.push(x);
    }
    Ok((nodes, map))
}

fn v22_nodes_binary(cur: &mut Cursor<'_>) -> Result<NodesAndMap, GmshError> {
    const SEC: &str = "$Nodes";
    // Record: int tag, then x y z as doubles.
    const REC: usize = 4 + 3 * 8;
    let n = count_line(cur, SEC, "the number of nodes")?;
    let start = cur.pos;
    let data = n
        .checked_mul(REC)
        .and_then(|len| cur.take(len))
        .ok_or_else(|| cur.truncated(SEC, format!("{n} binary node records of {REC} bytes")))?;
    let mut nodes = Vec::with_capacity(n);
    let mut map = HashMap::with_capacity(n);
    for (i, rec) in data.chunks_exact(REC).enumerate() {
        let at = start + i * REC;
        let tag = cur.i32_at(rec);
        let tag = usize::try_from(tag).map_err(|_| GmshError::Binary {
            offset: at,
            found: format!("node tag {tag}"),
            expected: "a non-negative node tag".into(),
        })?;
        let mut x = [0.0; 3];
        for (k, v) in x.iter_mut().enumerate() {
            *v = cur.f64_at(&rec[4 + 8 * k..]);
            if !v.is_finite() {
                return Err(GmshError::Binary {
                    offset: at + 4 + 8 * k,
                    found: format!("coordinate {v}"),
                    expected: "a finite coordinate".into(),
                });
            }
        }
        insert_node(&mut map, tag, i)?;
        nodes.push(x);
    }
    Ok((nodes, map))
}

/// Build an element from 2.2 data (tags = physical, elementary, ...).
fn make_element(
    elm: usize,
    ty: i32,
    tags: &[i32],
    node_tags: impl IntoIterator<Item = usize>,
    map: &HashMap<usize, usize>,
) -> Result<GmshElement, GmshError> {
    let nodes = node_tags
        .into_iter()
        .map(|t| {
            map.get(&t).copied().ok_or(GmshError::UnknownNodeTag {
                tag: t,
                element: elm,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(GmshElement {
        kind: GmshCellKind::from_gmsh_type(ty),
        nodes,
        physical_tag: tags.first().copied().filter(|&t| t != 0),
        entity_tag: tags.get(1).copied().unwrap_or(0),
    })
}

fn v22_elements_ascii(
    cur: &mut Cursor<'_>,
    map: &HashMap<usize, usize>,
) -> Result<Vec<GmshElement>, GmshError> {
    const SEC: &str = "$Elements";
    let n = count_line(cur, SEC, "the number of elements")?;
    let mut elements = Vec::with_capacity(capacity(n, cur.b.len() - cur.pos, 8));
    for _ in 0..n {
        let (line, at) = cur.section_line(SEC, "the remaining element lines")?;
        let toks: Vec<&[u8]> = line
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty())
            .collect();
        let shape = "an element line \"number type ntags tags... nodes...\"";
        if toks.len() < 3 {
            return Err(cur.err(at, show(line), shape));
        }
        let elm: usize = parse_tok(toks[0])
            .ok_or_else(|| cur.err(at, show(toks[0]), "a non-negative element number"))?;
        let ty: i32 = parse_tok(toks[1])
            .ok_or_else(|| cur.err(at, show(toks[1]), "an integer element type"))?;
        let ntags: usize = parse_tok(toks[2])
            .filter(|&k| k <= toks.len() - 3)
            .ok_or_else(|| {
                cur.err(
                    at,
                    show(toks[2]),
                    "the number of tags that follow on the line",
                )
            })?;
        let tags = toks[3..3 + ntags]
            .iter()
            .map(|t| parse_tok::<i32>(t).ok_or_else(|| cur.err(at, show(t), "an integer tag")))
            .collect::<Result<Vec<_>, _>>()?;
        let node_toks = &toks[3 + ntags..];
        // Unknown types are taken as given: their node count is whatever the line holds.
        let expected_nodes = type_info(ty).map_or(node_toks.len().max(1), |(k, _)| k);
        if node_toks.len() != expected_nodes {
            return Err(cur.err(
                at,
                format!("{} node tags", node_toks.len()),
                format!("{expected_nodes} node tags for element type {ty}"),
            ));
        }
        let node_tags = node_toks
            .iter()
            .map(|t| {
                parse_tok::<usize>(t).ok_or_else(|| cur.err(at, show(t), "a non-negative node tag"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        elements.push(make_element(elm, ty, &tags, node_tags, map)?);
    }
    Ok(elements)
}

fn v22_elements_binary(
    cur: &mut Cursor<'_>,
    map: &HashMap<usize, usize>,
) -> Result<Vec<GmshElement>, GmshError> {
    const SEC: &str = "$Elements";
    let n = count_line(cur, SEC, "the number of elements")?;
    let mut elements = Vec::with_capacity(capacity(n, cur.b.len() - cur.pos, 12));
    // Blocks of elements of one type: header (type, count, ntags), then the records.
    while elements.len() < n {
        let at = cur.pos;
        let head = cur
            .take(12)
            .ok_or_else(|| cur.truncated(SEC, format!("{} more elements", n - elements.len())))?;
        let (ty, count, ntags) = (
            cur.i32_at(head),
            cur.i32_at(&head[4..]),
            cur.i32_at(&head[8..]),
        );
        let left = n - elements.len();
        let count = usize::try_from(count)
            .ok()
            .filter(|&c| c >= 1 && c <= left)
            .ok_or_else(|| GmshError::Binary {
                offset: at + 4,
                found: format!("block of {count} elements"),
                expected: format!("between 1 and {left} elements (the rest of $Elements)"),
            })?;
        let ntags = usize::try_from(ntags).map_err(|_| GmshError::Binary {
            offset: at + 8,
            found: format!("{ntags} tags"),
            expected: "a non-negative number of tags".into(),
        })?;
        let (nn, _) = type_info(ty).ok_or_else(|| GmshError::Binary {
            offset: at,
            found: format!("element type {ty}"),
            expected: "an element type with a known node count (1 to 31)".into(),
        })?;
        let rec_ints = 1 + ntags + nn;
        let start = cur.pos;
        let data = rec_ints
            .checked_mul(4)
            .and_then(|x| x.checked_mul(count))
            .and_then(|len| cur.take(len))
            .ok_or_else(|| cur.truncated(SEC, format!("{count} element records of type {ty}")))?;
        for (k, rec) in data.chunks_exact(4 * rec_ints).enumerate() {
            let ints: Vec<i32> = rec.chunks_exact(4).map(|c| cur.i32_at(c)).collect();
            let rec_at = start + k * 4 * rec_ints;
            let elm = usize::try_from(ints[0]).map_err(|_| GmshError::Binary {
                offset: rec_at,
                found: format!("element number {}", ints[0]),
                expected: "a non-negative element number".into(),
            })?;
            let node_tags = ints[1 + ntags..]
                .iter()
                .enumerate()
                .map(|(j, &t)| {
                    usize::try_from(t).map_err(|_| GmshError::Binary {
                        offset: rec_at + 4 * (1 + ntags + j),
                        found: format!("node tag {t}"),
                        expected: "a non-negative node tag".into(),
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            elements.push(make_element(elm, ty, &ints[1..1 + ntags], node_tags, map)?);
        }
    }
    Ok(elements)
}

// ---------------------------------------------------------------------------------------------
// MSH 4.1 (via mshio)
// ---------------------------------------------------------------------------------------------

/// Where the four header numbers of `$Nodes` or `$Elements` are, and their values.
struct BlockHeader {
    /// Byte range of the 4th number (max tag) in the file.
    max_tag: std::ops::Range<usize>,
    /// Total number of nodes or elements.
    count: u64,
}

/// Read `numEntityBlocks numX minTag maxTag` at the start of a 4.1 `$Nodes`/`$Elements`.
fn v41_block_header(
    cur: &Cursor<'_>,
    content: usize,
    header: &MeshFormat,
    section: &str,
) -> Result<BlockHeader, GmshError> {
    let mut c = cur.clone();
    c.pos = content;
    let mut values = [0u64; 4];
    let mut last = 0..0;
    if header.binary {
        let ds = header.data_size;
        for v in &mut values {
            let at = c.pos;
            let b = c.take(ds).ok_or_else(|| {
                c.truncated(section, "the four size_t numbers of the section header")
            })?;
            *v = c.uint_at(b, ds);
            last = at..at + ds;
        }
    } else {
        for v in &mut values {
            let (tok, at) = c
                .token()
                .ok_or_else(|| c.truncated(section, "the four numbers of the section header"))?;
            *v = parse_tok(tok).ok_or_else(|| {
                c.err(
                    at,
                    show(tok),
                    format!("a non-negative integer in the {section} header"),
                )
            })?;
            last = at..at + tok.len();
        }
    }
    if values[1] == 0 {
        // mshio 0.4 underflows (panics) on empty sections, so refuse them here.
        return Err(c.err(
            content,
            format!("{section} with 0 entries"),
            format!("a non-empty {section} section"),
        ));
    }
    Ok(BlockHeader {
        max_tag: last,
        count: values[1],
    })
}

fn parse_v41(mut cur: Cursor<'_>, header: &MeshFormat) -> Result<GmshMesh, GmshError> {
    let mut physical_names = Vec::new();
    let mut nodes_content = None;
    let mut elements_content = None;
    // Walk the sections: $PhysicalNames is ours (mshio skips it); the rest is left to mshio,
    // but we need the position of the $Nodes header to patch it (see below).
    while let Some((name, at)) = cur.next_section()? {
        let content = cur.pos;
        let slot = match name.as_str() {
            "PhysicalNames" => {
                physical_names.extend(parse_physical_names(&mut cur)?);
                continue;
            }
            "Nodes" => &mut nodes_content,
            "Elements" => &mut elements_content,
            _ => {
                cur.skip_section(&name)?;
                continue;
            }
        };
        if slot.is_some() {
            return Err(cur.err(
                at,
                show(name.as_bytes()),
                format!("a single ${name} section"),
            ));
        }
        *slot = Some(content);
        cur.skip_section(&name)?;
    }
    let nodes_content = nodes_content.ok_or(GmshError::MissingSection {
        section: "$Nodes".into(),
    })?;
    let elements_content = elements_content.ok_or(GmshError::MissingSection {
        section: "$Elements".into(),
    })?;
    let nodes_header = v41_block_header(&cur, nodes_content, header, "$Nodes")?;
    let elements_header = v41_block_header(&cur, elements_content, header, "$Elements")?;

    // mshio 0.4 drops the node tags when they are contiguous (max - min + 1 == count) and then
    // assumes file order == tag order, which Gmsh does not promise. Declaring the largest
    // possible max tag makes it keep every tag; the value is not used otherwise.
    let mut patched: Vec<u8> = Vec::with_capacity(cur.b.len() + 24);
    let r = nodes_header.max_tag.clone();
    patched.extend_from_slice(&cur.b[header.start..r.start]);
    let shift: isize;
    if header.binary {
        patched.extend(std::iter::repeat_n(0xff_u8, r.len()));
        shift = 0;
    } else {
        let text = u64::MAX.to_string();
        shift = text.len() as isize - r.len() as isize;
        patched.extend_from_slice(text.as_bytes());
    }
    patched.extend_from_slice(&cur.b[r.end..]);
    // Map an offset in `patched` back to the original file.
    let original = |p: usize| -> usize {
        let p = p + header.start;
        if p > r.start {
            (p as isize - shift).max(r.start as isize) as usize
        } else {
            p
        }
    };

    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(&patched).map_err(|e| describe_mshio_error(&e, &patched))
    });
    let msh = match parsed {
        Ok(Ok(msh)) => msh,
        Ok(Err((pos, found, expected))) => {
            let offset = original(pos);
            if pos >= patched.len() {
                return Err(GmshError::Truncated {
                    section: expected.split(" > ").next().unwrap_or("").to_string(),
                    offset,
                    expected,
                });
            }
            return Err(cur.err(offset, found, expected));
        }
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            return Err(GmshError::ParserPanic { message });
        }
    };
    convert_v41(msh, physical_names, &nodes_header, &elements_header)
}

/// (offset in the parsed buffer, found, expected) for an mshio error.
fn describe_mshio_error(e: &mshio::MshParserError<&[u8]>, buf: &[u8]) -> (usize, String, String) {
    let base = buf.as_ptr() as usize;
    // The first backtrace entry is where parsing failed; later ones are enclosing contexts.
    let pos = e
        .backtrace
        .first()
        .map_or(0, |(i, _)| (i.as_ptr() as usize).saturating_sub(base))
        .min(buf.len());
    let rest = &buf[pos..];
    let line_end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
    let found = if rest.is_empty() {
        "end of file".to_string()
    } else {
        // Binary or text, show a little of what is there.
        let snippet = &rest[..line_end.clamp(1, 40)];
        if snippet.iter().all(|c| c.is_ascii_graphic() || *c == b' ') {
            show(snippet)
        } else {
            show_hex(rest)
        }
    };
    let mut parts: Vec<String> = e
        .backtrace
        .iter()
        .rev()
        .filter(|(_, k)| !k.is_nom_error())
        .map(|(_, k)| k.to_string())
        .collect();
    parts.dedup();
    let expected = if parts.is_empty() {
        "valid MSH 4.1 content".to_string()
    } else {
        parts.join(" > ")
    };
    (pos, found, expected)
}

fn convert_v41(
    msh: mshio::MshFile<u64, i32, f64>,
    physical_names: Vec<(i32, i32, String)>,
    nodes_header: &BlockHeader,
    elements_header: &BlockHeader,
) -> Result<GmshMesh, GmshError> {
    let nodes_sec = msh.data.nodes.ok_or(GmshError::MissingSection {
        section: "$Nodes".into(),
    })?;
    let elements_sec = msh.data.elements.ok_or(GmshError::MissingSection {
        section: "$Elements".into(),
    })?;

    let mut nodes = Vec::new();
    let mut tag_to_index: HashMap<usize, usize> = HashMap::new();
    for block in &nodes_sec.node_blocks {
        let tags = block.node_tags.as_ref().ok_or_else(|| GmshError::Invalid {
            found: "a node block without node tags".into(),
            expected: "mshio to keep node tags (forced by the max-tag patch)".into(),
        })?;
        // mshio stores tag -> position in block; restore position -> tag.
        let mut by_pos = vec![None; block.nodes.len()];
        for (&tag, &pos) in tags {
            let tag = usize::try_from(tag).map_err(|_| GmshError::Invalid {
                found: format!("node tag {tag}"),
                expected: "a node tag that fits in usize".into(),
            })?;
            if let Some(slot) = by_pos.get_mut(pos) {
                *slot = Some(tag);
            }
        }
        for (node, tag) in block.nodes.iter().zip(by_pos) {
            // A hole means two nodes of this block had the same tag (mshio kept only one).
            let tag = tag.ok_or_else(|| GmshError::Invalid {
                found: format!(
                    "{} distinct node tags for {} nodes in the block of entity ({}, {})",
                    tags.len(),
                    block.nodes.len(),
                    block.entity_dim,
                    block.entity_tag
                ),
                expected: "unique node tags".into(),
            })?;
            let x = [node.x, node.y, node.z];
            if x.iter().any(|v| !v.is_finite()) {
                return Err(GmshError::Invalid {
                    found: format!("node {tag} at {x:?}"),
                    expected: "finite coordinates".into(),
                });
            }
            insert_node(&mut tag_to_index, tag, nodes.len())?;
            nodes.push(x);
        }
    }
    if nodes.len() as u64 != nodes_header.count {
        return Err(GmshError::Invalid {
            found: format!("{} nodes in the node blocks", nodes.len()),
            expected: format!("{} nodes as the $Nodes header says", nodes_header.count),
        });
    }

    // Physical group of each entity: (dim, entity tag) -> first physical tag.
    let mut physical: HashMap<(i32, i32), i32> = HashMap::new();
    if let Some(ent) = &msh.data.entities {
        let mut add = |dim: i32, tag: i32, phys: &[i32]| {
            if let Some(&p) = phys.iter().find(|&&p| p != 0) {
                physical.insert((dim, tag), p);
            }
        };
        ent.points
            .iter()
            .for_each(|e| add(0, e.tag, &e.physical_tags));
        ent.curves
            .iter()
            .for_each(|e| add(1, e.tag, &e.physical_tags));
        ent.surfaces
            .iter()
            .for_each(|e| add(2, e.tag, &e.physical_tags));
        ent.volumes
            .iter()
            .for_each(|e| add(3, e.tag, &e.physical_tags));
    }

    let mut elements = Vec::new();
    for block in &elements_sec.element_blocks {
        let kind = GmshCellKind::from_gmsh_type(block.element_type as i32);
        let physical_tag = physical.get(&(block.entity_dim, block.entity_tag)).copied();
        for e in &block.elements {
            let element = usize::try_from(e.element_tag).unwrap_or(usize::MAX);
            let nodes = e
                .nodes
                .iter()
                .map(|&t| {
                    let tag = usize::try_from(t).unwrap_or(usize::MAX);
                    tag_to_index
                        .get(&tag)
                        .copied()
                        .ok_or(GmshError::UnknownNodeTag { tag, element })
                })
                .collect::<Result<Vec<_>, _>>()?;
            elements.push(GmshElement {
                kind,
                nodes,
                physical_tag,
                entity_tag: block.entity_tag,
            });
        }
    }
    if elements.len() as u64 != elements_header.count {
        return Err(GmshError::Invalid {
            found: format!("{} elements in the element blocks", elements.len()),
            expected: format!(
                "{} elements as the $Elements header says",
                elements_header.count
            ),
        });
    }
    Ok(GmshMesh {
        nodes,
        elements,
        physical_names,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_TRIS: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 5 \"plate with hole\"\n$EndPhysicalNames\n$Nodes\n4\n10 0 0 0\n30 1 0 0\n20 1 1 0\n40 0 1 0\n$EndNodes\n$Elements\n2\n1 2 2 5 1 10 30 20\n2 2 2 5 1 10 20 40\n$EndElements\n";

    #[test]
    fn v22_ascii_sparse_tags() {
        let m = parse_gmsh(TWO_TRIS.as_bytes()).expect("valid");
        assert_eq!(m.nodes.len(), 4);
        assert_eq!(m.elements[0].nodes, vec![0, 1, 2]);
        assert_eq!(m.elements[1].nodes, vec![0, 2, 3]);
        assert_eq!(m.elements[0].physical_tag, Some(5));
        assert_eq!(m.physical_tag_by_name("plate with hole"), Some((2, 5)));
        assert_eq!(m.highest_dimension(), Some(2));
    }

    #[test]
    fn unknown_node_tag() {
        let bad = TWO_TRIS.replace("10 20 40", "10 20 41");
        match parse_gmsh(bad.as_bytes()) {
            Err(GmshError::UnknownNodeTag {
                tag: 41,
                element: 2,
            }) => {}
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn parse_error_names_line() {
        let bad = TWO_TRIS.replace("30 1 0 0", "30 1 zero 0");
        match parse_gmsh(bad.as_bytes()) {
            Err(GmshError::Parse {
                line: 11, found, ..
            }) => assert!(found.contains("zero")),
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn version_check() {
        let bad = TWO_TRIS.replace("2.2 0 8", "3.0 0 8");
        assert!(matches!(
            parse_gmsh(bad.as_bytes()),
            Err(GmshError::UnsupportedVersion { .. })
        ));
    }
}
