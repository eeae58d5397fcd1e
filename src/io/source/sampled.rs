//! Points sampled on the faces of a mesh (`process --sample-faces N`): instead of a mesh's
//! vertices, N points drawn uniformly by area on its triangles (polygons fan-triangulated), each
//! carrying the exact unit normal of its triangle as a file normal.
//!
//! The mesh (vertices and triangles) is held in memory: 24 bytes per vertex and 20 per
//! triangle (indices and the cumulative-area table), small next to the LIDAR clouds the engine
//! streams; the N samples are never held, they are generated a chunk at a time in
//! [`PointSource::for_each_chunk`]. Point `i` is drawn from its own random stream
//! (`Rng::for_point(seed', i)`, `seed'` derived from the run's `--seed`), so the sample does not
//! depend on chunking or threads. A point picks a triangle by binary search of a uniform value
//! on the cumulative-area table, then a uniform point in it with sqrt-warped barycentrics
//! (Osada et al. 2002, "Shape distributions", eq. 1).
//!
//! Normals follow the faces' vertex order: counter-clockwise seen from outside is outward, the
//! convention of OBJ, OFF and PLY. Each format's reader (`mesh.rs`, `ply.rs`) hands its faces to
//! a [`Faces`] collector (`faces.rs`), which checks the indices and fan-triangulates.

use std::path::{Path, PathBuf};

use crate::core::geometry::{cross, dot, sub, SurfacePoint, V3};
use crate::core::rng::Rng;
use crate::error::{Error, Result};
use crate::io::crs::UnitSource;
use crate::io::las::extra_bytes::ScalarType;

use super::faces::Faces;
use super::{
    map_file, mesh, no_crs, ply, Format, PointSource, Property, SourceLayout, SourcePoint, Stored,
};

/// Mixed into the run's seed so that the sample's random streams (`Rng::for_point(seed', i)`)
/// are independent of the estimators' per-point streams (`Rng::for_point(seed, key)`, the key
/// a hash of the point's position).
const SAMPLE_STREAM: u64 = 0x5a4d_504c_4546_4143; // "ZMPLEFAC"

/// Opens `path` as `n` points sampled on its faces with the run's `seed` (see the module doc).
/// A usage error when the file is not a mesh or has no faces; a bad-input error, with the line
/// or byte offset, for a malformed face.
pub fn open(path: &Path, n: u64, seed: u64) -> Result<Box<dyn PointSource>> {
    let format = super::detect(path)?;
    let no_faces = |why: &str| {
        Error::Usage(format!(
            "{}: --sample-faces needs a mesh with faces, but {why}; drop --sample-faces to process the points as they are",
            path.display()
        ))
    };
    if !matches!(format, Format::Obj | Format::Off | Format::Ply) {
        return Err(no_faces(
            "this format has none (meshes are read from OBJ, OFF and PLY)",
        ));
    }
    let vertex_source = super::open_format(path, format)?;
    let mut vertices = Vec::with_capacity(vertex_source.len() as usize);
    let rl = vertex_source.record_length();
    vertex_source.for_each_chunk(1 << 16, &mut |first, records| {
        for (i, rec) in records.chunks_exact(rl).enumerate() {
            vertices.push(vertex_source.decode(first + i as u64, rec).xyz);
        }
        Ok(())
    })?;
    let what = vertex_source.describe();
    drop(vertex_source);
    let map = map_file(path)?;
    let base = if format == Format::Obj { 1 } else { 0 };
    let mut faces = Faces::new(path, vertices.len(), base)?;
    let found = match format {
        Format::Obj => mesh::obj_faces(&map, &mut faces)?,
        Format::Off => mesh::off_faces(path, &map, &mut faces)?,
        _ => ply::read_faces(path, &map, &mut faces)?,
    };
    if !found || faces.polygons() == 0 {
        return Err(no_faces("the file declares no faces"));
    }
    let polygons = faces.polygons();
    let mesh = TriangleTable::new(&vertices, faces.into_triangles()).ok_or_else(|| {
        Error::bad_input(
            path,
            None,
            format!("all {polygons} faces have zero area: there is no surface to sample"),
        )
    })?;
    let describe = format!(
        "{n} points sampled on {} triangles ({polygons} faces, area {:.6e}) of a mesh read as {what}",
        mesh.tris.len(),
        mesh.area()
    );
    Ok(Box::new(SampledSource {
        path: path.to_path_buf(),
        vertices,
        mesh,
        n,
        seed: seed ^ SAMPLE_STREAM,
        describe,
    }))
}

/// The triangles of positive area with their cumulative areas (degenerate triangles can never
/// be drawn and are dropped).
struct TriangleTable {
    tris: Vec<[u32; 3]>,
    /// `cum[i]`: the area of triangles 0..=i.
    cum: Vec<f64>,
}

impl TriangleTable {
    /// None when no triangle has a positive area.
    fn new(vertices: &[V3], mut tris: Vec<[u32; 3]>) -> Option<Self> {
        let area = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            let n = cross(sub(b, a), sub(c, a));
            0.5 * dot(n, n).sqrt()
        };
        tris.retain(|t| area(t) > 0.0);
        if tris.is_empty() {
            return None;
        }
        let mut total = 0.0;
        let cum = tris
            .iter()
            .map(|t| {
                total += area(t);
                total
            })
            .collect();
        Some(TriangleTable { tris, cum })
    }

    fn area(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// The triangle whose cumulative-area interval holds `u * area` (u in [0, 1)).
    fn pick(&self, u: f64) -> [u32; 3] {
        let r = u * self.area();
        let i = self.cum.partition_point(|&c| c <= r);
        self.tris[i.min(self.tris.len() - 1)]
    }
}

/// N points sampled on a mesh's faces (see the module doc). Records: x y z nx ny nz as f64.
pub struct SampledSource {
    path: PathBuf,
    vertices: Vec<V3>,
    mesh: TriangleTable,
    n: u64,
    seed: u64,
    describe: String,
}

const NAMES: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];

impl SampledSource {
    /// Point `i` of the sample: its position and the unit normal of its triangle.
    fn point(&self, i: u64) -> SurfacePoint {
        let mut rng = Rng::for_point(self.seed, i);
        let [a, b, c] = self
            .mesh
            .pick(rng.uniform())
            .map(|v| self.vertices[v as usize]);
        let s = rng.uniform().sqrt();
        let r2 = rng.uniform();
        let (wa, wb, wc) = (1.0 - s, s * (1.0 - r2), s * r2);
        let p = [0, 1, 2].map(|k| wa * a[k] + wb * b[k] + wc * c[k]);
        let n = cross(sub(b, a), sub(c, a));
        let len = dot(n, n).sqrt();
        SurfacePoint {
            position: p,
            normal: n.map(|x| x / len),
        }
    }
}

impl PointSource for SampledSource {
    fn path(&self) -> &Path {
        &self.path
    }

    fn len(&self) -> u64 {
        self.n
    }

    fn has_normals(&self) -> bool {
        true
    }

    fn unit(&self) -> UnitSource {
        no_crs("a sampled mesh")
    }

    fn record_length(&self) -> usize {
        8 * NAMES.len()
    }

    /// Generates the points `chunk_points` at a time.
    fn for_each_chunk(
        &self,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let chunk = chunk_points.clamp(1, 1 << 20) as u64;
        let mut buf = Vec::with_capacity(chunk as usize * self.record_length());
        let mut first = 0u64;
        while first < self.n {
            let end = (first + chunk).min(self.n);
            buf.clear();
            for i in first..end {
                let s = self.point(i);
                for v in s.position.iter().chain(&s.normal) {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
            f(first, &buf)?;
            first = end;
        }
        Ok(())
    }

    fn decode(&self, id: u64, rec: &[u8]) -> SourcePoint {
        let at = |i: usize| ScalarType::F64.decode(&rec[8 * i..]);
        SourcePoint {
            id,
            xyz: [at(0), at(1), at(2)],
            normal: Some([at(3), at(4), at(5)]),
        }
    }

    fn describe(&self) -> String {
        self.describe.clone()
    }

    fn layout(&self) -> SourceLayout<'_> {
        SourceLayout::Converted
    }

    fn properties(&self) -> Vec<Property> {
        NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| Property::new(*n, ScalarType::F64, Stored::Le(8 * i)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &[u8]) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        (dir, p)
    }

    fn points(s: &dyn PointSource, chunk: usize) -> Vec<SourcePoint> {
        let mut v = Vec::new();
        let rl = s.record_length();
        s.for_each_chunk(chunk, &mut |first, r| {
            for (i, rec) in r.chunks_exact(rl).enumerate() {
                v.push(s.decode(first + i as u64, rec));
            }
            Ok(())
        })
        .expect("samples");
        v
    }

    fn message(r: Result<Box<dyn PointSource>>) -> String {
        match r {
            Ok(_) => panic!("accepted"),
            Err(e) => e.to_string(),
        }
    }

    /// A unit square (two triangles, z = 0, counter-clockwise from +z) and a degenerate face.
    const SQUARE_OBJ: &[u8] = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2//3 3/4/5 4\nf 1 1 2\n";

    #[test]
    fn square_samples_lie_on_it_with_the_outward_normal() {
        let (_d, p) = write("sq.obj", SQUARE_OBJ);
        let s = open(&p, 1000, 7).expect("opens");
        assert_eq!(s.len(), 1000);
        let pts = points(s.as_ref(), 333);
        assert_eq!(pts.len(), 1000);
        for q in &pts {
            assert!(q.xyz.iter().take(2).all(|c| (0.0..=1.0).contains(c)) && q.xyz[2] == 0.0);
            assert_eq!(q.normal, Some([0.0, 0.0, 1.0]));
        }
        // Uniform by area: about half the points in each triangle (x > y or not).
        let above = pts.iter().filter(|q| q.xyz[0] > q.xyz[1]).count();
        assert!((400..600).contains(&above), "{above}");
        // Independent of chunking, dependent on the seed.
        assert_eq!(points(s.as_ref(), 1), pts);
        let t = open(&p, 1000, 8).expect("opens");
        assert_ne!(points(t.as_ref(), 1000), pts);
    }

    #[test]
    fn relative_obj_indices_and_clockwise_faces() {
        let (_d, p) = write("cw.obj", b"v 0 0 0\nv 0 1 0\nv 1 0 0\nf -3 -2 -1\n");
        let s = open(&p, 10, 0).expect("opens");
        assert!(points(s.as_ref(), 10)
            .iter()
            .all(|q| q.normal == Some([0.0, 0.0, -1.0])));
    }

    #[test]
    fn off_and_ply_faces() {
        let (_d, p) = write(
            "a.off",
            b"OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n",
        );
        assert_eq!(points(open(&p, 50, 0).expect("off").as_ref(), 50).len(), 50);
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty uchar flags\nproperty list uchar int vertex_indices\nend_header\n";
        let (_d, p) = write(
            "a.ply",
            format!("{head}0 0 0\n0 0 1\n0 1 0\n7 3 0 1 2\n").as_bytes(),
        );
        let s = open(&p, 5, 0).expect("ascii ply");
        assert!(points(s.as_ref(), 5)
            .iter()
            .all(|q| q.normal == Some([-1.0, 0.0, 0.0])));
        // Other face properties, lists of floats included, are skipped; extra values are not.
        let with_uv = head.replace(
            "end_header",
            "property list uchar float texcoord\nproperty float quality\nend_header",
        );
        let (_d, p) = write(
            "uv.ply",
            format!("{with_uv}0 0 0\n0 0 1\n0 1 0\n7 3 0 1 2 2 0.5 0.25 0.9\n").as_bytes(),
        );
        assert_eq!(points(open(&p, 5, 0).expect("uv").as_ref(), 5).len(), 5);
        let (_d, p) = write(
            "uv2.ply",
            format!("{with_uv}0 0 0\n0 0 1\n0 1 0\n7 3 0 1 2 2 0.5 0.25 0.9 4\n").as_bytes(),
        );
        assert!(message(open(&p, 5, 0)).contains("line 16: the face line has more values"));
        let (_d, p) = write(
            "uv3.ply",
            format!("{with_uv}0 0 0\n0 0 1\n0 1 0\n7 3 0 1.5 2 2 0.5 0.25 0.9\n").as_bytes(),
        );
        let m = message(open(&p, 5, 0));
        assert!(
            m.contains("line 16: vertex_indices item 2 is \"1.5\", not an integer"),
            "{m}"
        );
        // The same in binary big endian, then with an index out of range.
        let bin = |last: i32| {
            let mut b = head.replace("ascii", "binary_big_endian").into_bytes();
            for v in [[0f32, 0., 0.], [0., 0., 1.], [0., 1., 0.]] {
                for c in v {
                    b.extend_from_slice(&c.to_be_bytes());
                }
            }
            b.extend_from_slice(&[7, 3]);
            for i in [0, 1, last] {
                b.extend_from_slice(&i.to_be_bytes());
            }
            b
        };
        let (_d, p) = write("b.ply", &bin(2));
        let s = open(&p, 5, 0).expect("binary ply");
        assert!(points(s.as_ref(), 5)
            .iter()
            .all(|q| q.normal == Some([-1.0, 0.0, 0.0])));
        let (_d, p) = write("c.ply", &bin(3));
        // The offset of the face record: after the binary header and the three vertices.
        let at = head.replace("ascii", "binary_big_endian").len() + 36;
        let m = message(open(&p, 5, 0));
        assert!(
            m.contains("face vertex index 3 is out of range")
                && m.contains(&format!("byte offset {at}")),
            "{m}"
        );
        let mut short = bin(2);
        short.truncate(short.len() - 2);
        let (_d, p) = write("d.ply", &short);
        let m = message(open(&p, 5, 0));
        assert!(m.contains("truncated"), "{m}");
    }

    #[test]
    fn files_without_faces_are_usage_errors_and_bad_faces_name_the_line() {
        let usage = |name: &str, text: &[u8]| {
            let (_d, p) = write(name, text);
            match open(&p, 10, 0) {
                Err(e @ Error::Usage(_)) => assert!(e.to_string().contains(name), "{e}"),
                Err(e) => panic!("{e}"),
                Ok(_) => panic!("accepted"),
            }
        };
        usage("a.xyz", b"0 0 0\n1 0 0\n0 1 0\n");
        usage("b.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        usage("c.off", b"OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n");
        let bad = |name: &str, text: &[u8], want: &str| {
            let (_d, p) = write(name, text);
            let m = message(open(&p, 10, 0));
            assert!(m.contains(want), "{m}");
        };
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        bad(
            "r.obj",
            format!("{v}f 1 2 4\n").as_bytes(),
            "line 4: face vertex index 4 is out of range: the file has 3 vertices, numbered 1 to 3",
        );
        bad(
            "s.obj",
            format!("{v}f 1 2\n").as_bytes(),
            "line 4: a face has 2 vertices",
        );
        bad(
            "t.obj",
            format!("{v}f 1 2 x/1\n").as_bytes(),
            "line 4: face vertex \"x/1\" is not an integer",
        );
        bad(
            "z.obj",
            format!("{v}f 0 1 2\n").as_bytes(),
            "line 4: face vertex index 0",
        );
        bad("d.obj", format!("{v}f 1 1 2\n").as_bytes(), "zero area");
        let off = "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n";
        bad(
            "r.off",
            format!("{off}3 0 1 2\n3 0 1 3\n").as_bytes(),
            "line 7: face vertex index 3 is out of range",
        );
        bad(
            "s.off",
            format!("{off}3 0 1 2\n4 0 1 2\n").as_bytes(),
            "line 7: the face declares 4 vertices but lists 3",
        );
        bad(
            "t.off",
            format!("{off}3 0 1 2\n").as_bytes(),
            "declares 2 faces but the file ends after 1",
        );
        bad(
            "u.off",
            format!("{off}3 0 1 2\n3 0 1.5 2\n").as_bytes(),
            "line 7: face vertex \"1.5\" is not an integer",
        );
    }
}
