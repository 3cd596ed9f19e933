//! Reader for Gmsh `.msh` meshes: MSH 2.2 and 4.1, ASCII and binary.
//!
//! * 4.1 is parsed by the `mshio` crate; `v41` adds what `mshio` 0.4 leaves out
//!   (`$PhysicalNames`, node tags of contiguously numbered files) and guards against its panics.
//! * 2.2 (ASCII and binary) is parsed by hand in `v22`, since `mshio` only knows 4.1.
//! * [`from_gmsh_file`] turns a file into a [`Mesh`]: the body cells and named node sets.
//!
//! Node tags in a file are arbitrary (sparse, unordered); [`GmshMesh::nodes`] holds the nodes
//! densely in file order and [`GmshElement::nodes`] indexes into it (0-based).
//!
//! Corrupt or truncated input gives a [`GmshError`], never a panic. Errors name what was found,
//! what was expected, and where (line for ASCII, byte offset for binary data).

mod cursor;
mod header;
mod v22;
mod v41;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::SVector;

use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::Error;
use crate::mesh::{CellBlock, Mesh};
use cursor::Cursor;
use header::{parse_mesh_format, Version};

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
    /// The element's own tag (number) in the file.
    pub tag: usize,
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
        Version::V22 => v22::parse_v22(cur, &header),
        Version::V41 => v41::parse_v41(cur, &header),
    }
}

/// Record a node; a tag seen before is an error.
fn insert_node(map: &mut HashMap<usize, usize>, tag: usize, index: usize) -> Result<(), GmshError> {
    if map.insert(tag, index).is_some() {
        return Err(GmshError::DuplicateNodeTag { tag });
    }
    Ok(())
}

/// Reads a Gmsh MSH file (2.2 or 4.1, ASCII or binary) as a D-dimensional mesh: the cells of
/// the highest dimension form the body (they must be D-dimensional); every physical group
/// becomes a named node set (the nodes of its elements, any dimension). Nodes used by no body
/// cell are dropped and the rest renumbered in file order.
pub fn from_gmsh_file<const D: usize>(path: &Path) -> crate::error::Result<Mesh<D>>
where
    Dim<D>: SpatialDim<D>,
{
    let file_error = |message: String| Error::MeshFile {
        file: path.to_path_buf(),
        message,
    };
    let g = read_gmsh(path).map_err(|e| file_error(e.to_string()))?;
    from_gmsh(&g).map_err(file_error)
}

/// The file's element tag of each cell of [`from_gmsh`]'s mesh, in the mesh's cell order
/// (blocks of one kind in order of first appearance, file order within a block), so that
/// messages about a cell can name the element a user sees in Gmsh.
pub fn cell_tags<const D: usize>(g: &GmshMesh) -> Vec<usize> {
    let cells: Vec<&GmshElement> = g
        .elements
        .iter()
        .filter(|el| el.kind.dimension() == Some(D))
        .collect();
    let mut kinds: Vec<GmshCellKind> = Vec::new();
    for el in &cells {
        if !kinds.contains(&el.kind) {
            kinds.push(el.kind);
        }
    }
    kinds
        .iter()
        .flat_map(|k| {
            cells
                .iter()
                .filter(move |el| el.kind == *k)
                .map(|el| el.tag)
        })
        .collect()
}

/// Converts a parsed Gmsh mesh (see [`from_gmsh_file`]).
pub fn from_gmsh<const D: usize>(g: &GmshMesh) -> std::result::Result<Mesh<D>, String>
where
    Dim<D>: SpatialDim<D>,
{
    use GmshCellKind as G;
    let top = g.highest_dimension().ok_or("the file has no element")?;
    if top != D {
        return Err(format!(
            "found {top}D elements as the highest dimension; expected {D}D cells"
        ));
    }
    let mut renumber = vec![usize::MAX; g.nodes.len()];
    let mut nodes = Vec::new();
    let mut blocks: Vec<CellBlock> = Vec::new();
    for (e, el) in g.elements.iter().enumerate() {
        if el.kind.dimension() != Some(D) {
            continue;
        }
        let kind = match el.kind {
            G::Tri3 => ElementKind::Tri3,
            G::Quad4 => ElementKind::Quad4,
            G::Tet4 => ElementKind::Tet4,
            G::Hex8 => ElementKind::Hex8,
            other => {
                return Err(format!(
                    "element {e} has Gmsh type {}; expected linear tri3, quad4, tet4 or hex8",
                    other.gmsh_type()
                ))
            }
        };
        let block = match blocks.iter_mut().position(|b| b.kind == kind) {
            Some(i) => &mut blocks[i],
            None => {
                blocks.push(CellBlock {
                    kind,
                    connectivity: Vec::new(),
                });
                blocks.last_mut().expect("just pushed")
            }
        };
        for &n in &el.nodes {
            if renumber[n] == usize::MAX {
                renumber[n] = nodes.len();
                let mut x = SVector::<f64, D>::zeros();
                for k in 0..D {
                    x[k] = g.nodes[n][k];
                }
                nodes.push(x);
            }
            block.connectivity.push(renumber[n]);
        }
    }
    let mut node_sets: HashMap<String, Vec<usize>> = HashMap::new();
    for (dim, tag, name) in &g.physical_names {
        let mut set: Vec<usize> = g
            .elements
            .iter()
            .filter(|el| {
                el.physical_tag == Some(*tag) && el.kind.dimension() == Some(*dim as usize)
            })
            .flat_map(|el| el.nodes.iter().map(|&n| renumber[n]))
            .filter(|&n| n != usize::MAX)
            .collect();
        set.sort_unstable();
        set.dedup();
        node_sets.insert(name.clone(), set);
    }
    Ok(Mesh {
        nodes,
        blocks,
        node_sets,
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
