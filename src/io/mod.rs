//! Input and output: scene files, history CSV, summary JSON, VTK.

pub mod output;
pub mod scene;
pub mod vtk;
