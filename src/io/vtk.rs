//! VTK output: XML unstructured grids (`.vtu`) and ParaView collections (`.pvd`).
//!
//! Both are a few lines of XML written here. `.vtu` data arrays are `Float64` (points and
//! fields), `UInt64` (connectivity, offsets) and `UInt8` (cell types), in VTK's inline "binary"
//! format: base64 of a little-endian `UInt64` byte count followed by the values (XML format
//! version 1.0, `header_type="UInt64"`). ParaView, VTK/pyvista and meshio read them.
//!
//! Both writers write `<path>.tmp` and rename it over `<path>`, so a viewer polling the
//! output never sees a half-written file.
//!
//! Node order: for the linear cells here, Gmsh and VTK number nodes the same way (lines
//! 0-1; triangles and quads counter-clockwise; tetrahedra with node 3 on the positive side
//! of face 0-1-2; hexahedra with the bottom face 0-3 counter-clockwise seen from the top
//! face 4-7, node 4 above node 0). Connectivity is written unchanged.

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic;

/// Linear cell kinds that can be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VtkCellKind {
    /// 2-node line (`VTK_LINE`, 3).
    Line2,
    /// 3-node triangle (`VTK_TRIANGLE`, 5).
    Tri3,
    /// 4-node quadrilateral (`VTK_QUAD`, 9).
    Quad4,
    /// 4-node tetrahedron (`VTK_TETRA`, 10).
    Tet4,
    /// 8-node hexahedron (`VTK_HEXAHEDRON`, 12).
    Hex8,
}

impl VtkCellKind {
    /// The VTK cell type id.
    pub fn vtk_type(self) -> u8 {
        match self {
            Self::Line2 => 3,
            Self::Tri3 => 5,
            Self::Quad4 => 9,
            Self::Tet4 => 10,
            Self::Hex8 => 12,
        }
    }

    /// Number of nodes of a cell of this kind.
    pub fn node_count(self) -> usize {
        match self {
            Self::Line2 => 2,
            Self::Tri3 => 3,
            Self::Quad4 | Self::Tet4 => 4,
            Self::Hex8 => 8,
        }
    }
}

/// A named field on points or cells.
#[derive(Debug, Clone, Copy)]
pub struct VtkField<'a> {
    /// Array name shown by viewers; must be non-empty and unique among the piece's point
    /// (or cell) fields.
    pub name: &'a str,
    /// Components per entry (1 for scalars, 3 for vectors, 9 for tensors, ...).
    pub components: usize,
    /// Values, entry-major: `values.len() == n * components`, where `n` is the number of
    /// points (point data) or cells (cell data).
    pub values: &'a [f64],
}

/// One unstructured grid: points, cells, and fields on them.
///
/// Cells are `(kind, node indices)` pairs; the indices are 0-based into `points`, in VTK
/// order (which equals Gmsh order for these kinds). Cells of different kinds may be mixed;
/// cell data follows the order of `cells`.
#[derive(Debug, Clone, Copy)]
pub struct VtkPiece<'a> {
    /// Point coordinates.
    pub points: &'a [[f64; 3]],
    /// Cells as `(kind, node indices)`.
    pub cells: &'a [(VtkCellKind, &'a [usize])],
    /// Fields with one entry per point.
    pub point_data: &'a [VtkField<'a>],
    /// Fields with one entry per cell.
    pub cell_data: &'a [VtkField<'a>],
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// Check fields against the number of entries they must have.
fn check_fields(fields: &[VtkField<'_>], n: usize, what: &str) -> io::Result<()> {
    for (i, f) in fields.iter().enumerate() {
        if f.name.is_empty() {
            return Err(invalid(format!("{what} field {i} has an empty name")));
        }
        if fields[..i].iter().any(|g| g.name == f.name) {
            return Err(invalid(format!(
                "{what} field name {:?} is used twice",
                f.name
            )));
        }
        if f.components == 0 || u32::try_from(f.components).is_err() {
            return Err(invalid(format!(
                "{what} field {:?} has {} components, expected 1 to {}",
                f.name,
                f.components,
                u32::MAX
            )));
        }
        let expected = n.checked_mul(f.components);
        if expected != Some(f.values.len()) {
            return Err(invalid(format!(
                "{what} field {:?} has {} values, expected {n} {what}s x {} components",
                f.name,
                f.values.len(),
                f.components
            )));
        }
    }
    Ok(())
}

/// The checked piece in the arrays of a `.vtu` file.
#[derive(Debug)]
struct Arrays {
    connectivity: Vec<u64>,
    offsets: Vec<u64>,
    types: Vec<u8>,
}

/// Check the piece for consistency and flatten its cells.
fn to_arrays(piece: &VtkPiece<'_>) -> io::Result<Arrays> {
    let n_points = piece.points.len();
    let mut connectivity = Vec::new();
    let mut offsets = Vec::with_capacity(piece.cells.len());
    let mut types = Vec::with_capacity(piece.cells.len());
    for (c, (kind, nodes)) in piece.cells.iter().enumerate() {
        if nodes.len() != kind.node_count() {
            return Err(invalid(format!(
                "cell {c} ({kind:?}) has {} nodes, expected {}",
                nodes.len(),
                kind.node_count()
            )));
        }
        if let Some(&bad) = nodes.iter().find(|&&i| i >= n_points) {
            return Err(invalid(format!(
                "cell {c} ({kind:?}) refers to point {bad}, expected an index below {n_points}"
            )));
        }
        connectivity.extend(nodes.iter().map(|&i| i as u64));
        offsets.push(connectivity.len() as u64);
        types.push(kind.vtk_type());
    }
    check_fields(piece.point_data, n_points, "point")?;
    check_fields(piece.cell_data, piece.cells.len(), "cell")?;
    Ok(Arrays {
        connectivity,
        offsets,
        types,
    })
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// One `<DataArray>` in VTK's inline binary format: base64 of the `UInt64` byte count and the
/// little-endian values.
fn data_array<T: Copy>(
    w: &mut impl Write,
    vtk_type: &str,
    name: Option<&str>,
    components: usize,
    values: &[T],
    to_le: impl Fn(T, &mut Vec<u8>),
) -> io::Result<()> {
    let mut bytes = Vec::with_capacity(8 + std::mem::size_of_val(values));
    bytes.extend_from_slice(&[0; 8]);
    for &v in values {
        to_le(v, &mut bytes);
    }
    let len = (bytes.len() - 8) as u64;
    bytes[..8].copy_from_slice(&len.to_le_bytes());
    write!(w, "        <DataArray type=\"{vtk_type}\"")?;
    if let Some(name) = name {
        write!(w, " Name=\"{}\"", xml_escape(name))?;
    }
    writeln!(
        w,
        " NumberOfComponents=\"{components}\" format=\"binary\">{}</DataArray>",
        base64(&bytes)
    )
}

fn f64_array(w: &mut impl Write, name: Option<&str>, comps: usize, v: &[f64]) -> io::Result<()> {
    data_array(w, "Float64", name, comps, v, |x, b| {
        b.extend_from_slice(&x.to_le_bytes())
    })
}

/// `<PointData>` or `<CellData>` with one array per field.
fn field_data(w: &mut impl Write, tag: &str, fields: &[VtkField<'_>]) -> io::Result<()> {
    if fields.is_empty() {
        return writeln!(w, "      <{tag}/>");
    }
    writeln!(w, "      <{tag}>")?;
    for f in fields {
        f64_array(w, Some(f.name), f.components, f.values)?;
    }
    writeln!(w, "      </{tag}>")
}

/// The whole `.vtu` document of a checked piece.
fn write_xml(w: &mut impl Write, piece: &VtkPiece<'_>, arrays: &Arrays) -> io::Result<()> {
    writeln!(w, "<?xml version=\"1.0\"?>")?;
    writeln!(
        w,
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">"
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        piece.points.len(),
        piece.cells.len()
    )?;
    field_data(w, "PointData", piece.point_data)?;
    field_data(w, "CellData", piece.cell_data)?;
    writeln!(w, "      <Points>")?;
    let points: Vec<f64> = piece.points.iter().flatten().copied().collect();
    f64_array(w, None, 3, &points)?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Cells>")?;
    let u64_le = |x: u64, b: &mut Vec<u8>| b.extend_from_slice(&x.to_le_bytes());
    data_array(
        w,
        "UInt64",
        Some("connectivity"),
        1,
        &arrays.connectivity,
        u64_le,
    )?;
    data_array(w, "UInt64", Some("offsets"), 1, &arrays.offsets, u64_le)?;
    data_array(w, "UInt8", Some("types"), 1, &arrays.types, |x, b| {
        b.push(x)
    })?;
    writeln!(w, "      </Cells>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")
}

/// Write `piece` as a VTK XML unstructured grid (`.vtu`) at `path`.
///
/// The piece is checked first (node counts per cell kind, point indices in range, field
/// lengths, unique non-empty names); problems give `ErrorKind::InvalidInput` and no file.
/// The file appears atomically (written to `<path>.tmp`, then renamed).
pub fn write_vtu(path: &Path, piece: &VtkPiece) -> io::Result<()> {
    let arrays = to_arrays(piece)?;
    write_atomic(path, false, |w| write_xml(w, piece, &arrays))
}

/// Escape text for an XML attribute value.
fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// Write a ParaView collection (`.pvd`) listing `(time, file)` entries, for animations.
///
/// File paths are written as given; ParaView resolves them relative to the `.pvd` file.
/// Times must be finite (`ErrorKind::InvalidInput` otherwise). Written atomically.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> io::Result<()> {
    let parts: Vec<(f64, usize, String)> =
        entries.iter().map(|(t, f)| (*t, 0, f.clone())).collect();
    write_pvd_parts(path, &parts)
}

/// Like [`write_pvd`], with a part number per entry (one part per body, so that ParaView shows
/// every body at every time).
pub fn write_pvd_parts(path: &Path, entries: &[(f64, usize, String)]) -> io::Result<()> {
    if let Some((t, _, f)) = entries.iter().find(|(t, _, _)| !t.is_finite()) {
        return Err(invalid(format!("time {t} of {f:?} is not finite")));
    }
    write_atomic(path, false, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(w, "  <Collection>")?;
        for (t, part, file) in entries {
            // `{:?}` prints the shortest text that reads back as the same f64.
            writeln!(
                w,
                "    <DataSet timestep=\"{t:?}\" group=\"\" part=\"{part}\" file=\"{}\"/>",
                xml_escape(file)
            )?;
        }
        writeln!(w, "  </Collection>")?;
        writeln!(w, "</VTKFile>")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape() {
        assert_eq!(xml_escape("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&apos;");
    }

    #[test]
    fn base64_matches_rfc_4648() {
        for (raw, encoded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), encoded);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn rejects_bad_pieces() {
        let points = [[0.0; 3]; 3];
        let tri: &[usize] = &[0, 1, 2];
        let bad: &[usize] = &[0, 1, 3];
        let short: &[usize] = &[0, 1];
        let vals = [1.0, 2.0];
        for (cells, point_data) in [
            (vec![(VtkCellKind::Tri3, bad)], vec![]),
            (vec![(VtkCellKind::Tri3, short)], vec![]),
            (
                vec![(VtkCellKind::Tri3, tri)],
                vec![VtkField {
                    name: "p",
                    components: 1,
                    values: &vals,
                }],
            ),
        ] {
            let piece = VtkPiece {
                points: &points,
                cells: &cells,
                point_data: &point_data,
                cell_data: &[],
            };
            let err = to_arrays(&piece).expect_err("invalid");
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        }
    }
}
