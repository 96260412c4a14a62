//! ParaView output: rods as line segments in VTK XML PolyData (`.vtp`), with point data
//! `radius`, `orientation` and `speed`, and a `.pvd` collection indexing the files by time.

use crate::io::{IoError, write_atomic};
use std::fmt::Write;
use std::path::Path;

/// Write rods (centres `x`, unit axes `p`, length `len`, radius, speeds) as a `.vtp` file.
pub fn write_rods_vtp(
    path: &Path,
    x: &[[f64; 3]],
    p: &[[f64; 3]],
    len: f64,
    radius: f64,
    speed: &[f64],
) -> Result<(), IoError> {
    let n = x.len();
    let mut s = String::with_capacity(200 * n + 1000);
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\">\n<PolyData>\n");
    let _ = writeln!(
        s,
        "<Piece NumberOfPoints=\"{}\" NumberOfLines=\"{n}\">",
        2 * n
    );
    s.push_str(
        "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n",
    );
    for (c, q) in x.iter().zip(p) {
        for sign in [-0.5, 0.5] {
            let _ = writeln!(
                s,
                "{} {} {}",
                c[0] + sign * len * q[0],
                c[1] + sign * len * q[1],
                c[2] + sign * len * q[2]
            );
        }
    }
    s.push_str("</DataArray>\n</Points>\n<Lines>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = writeln!(s, "{} {}", 2 * i, 2 * i + 1);
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = writeln!(s, "{}", 2 * i + 2);
    }
    s.push_str("</DataArray>\n</Lines>\n<PointData Scalars=\"speed\" Vectors=\"orientation\">\n");
    s.push_str("<DataArray type=\"Float64\" Name=\"radius\" format=\"ascii\">\n");
    for _ in 0..2 * n {
        let _ = writeln!(s, "{radius}");
    }
    s.push_str("</DataArray>\n<DataArray type=\"Float64\" Name=\"orientation\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for q in p {
        for _ in 0..2 {
            let _ = writeln!(s, "{} {} {}", q[0], q[1], q[2]);
        }
    }
    s.push_str("</DataArray>\n<DataArray type=\"Float64\" Name=\"speed\" format=\"ascii\">\n");
    for v in speed {
        let _ = writeln!(s, "{v}\n{v}");
    }
    s.push_str("</DataArray>\n</PointData>\n</Piece>\n</PolyData>\n</VTKFile>\n");
    write_atomic(path, s.as_bytes())
}

/// Write a `.pvd` collection of `(time, relative file name)` entries.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<(), IoError> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    for (t, f) in entries {
        let _ = writeln!(
            s,
            "<DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{f}\"/>"
        );
    }
    s.push_str("</Collection>\n</VTKFile>\n");
    write_atomic(path, s.as_bytes())
}
