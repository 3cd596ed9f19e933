//! Input and output (feature `formats`): scene files, Gmsh meshes, history CSV, summary JSON,
//! VTK, checkpoints. Every output file is written whole or not at all (`atomic`).

mod atomic;
pub mod checkpoint;
pub mod gmsh;
pub mod output;
pub mod scene;
pub mod vtk;
