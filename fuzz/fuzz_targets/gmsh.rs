//! The Gmsh reader (MSH 2.2 and 4.1, ASCII and binary) and the conversion to a mesh. Any
//! panic is a finding, and so is an empty error message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use softway::io::gmsh;

fuzz_target!(|data: &[u8]| {
    let outcome = gmsh::parse_gmsh(data)
        .map_err(|e| e.to_string())
        .and_then(|g| match g.highest_dimension() {
            Some(2) => gmsh::from_gmsh::<2>(&g).map(|_| ()),
            Some(3) => gmsh::from_gmsh::<3>(&g).map(|_| ()),
            _ => Ok(()),
        });
    if let Err(message) = outcome {
        assert!(!message.trim().is_empty(), "an empty error message");
    }
});
