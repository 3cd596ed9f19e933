//! Input and output (feature `formats`): scene files, Gmsh meshes, history CSV, summary JSON,
//! VTK.

pub mod gmsh;
pub mod output;
pub mod scene;
pub mod vtk;
