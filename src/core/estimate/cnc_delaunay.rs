//! CNC-Delaunay (algorithms.md 4.9): corrected curvature measures summed over local Delaunay
//! umbrellas (Sharp and Crane 2020). For each point of the neighbourhood, its neighbours are projected onto its
//! tangent plane (its own normal) and the triangles of the 2D Delaunay triangulation incident to
//! it (its umbrella, the 1-ring fan) are kept; all umbrella triangles, deduplicated, enter the
//! CNC sums of algorithms.md 4.3.
//!
//! Deviation from the paper: the estimator sees only the query's K-NN, so each umbrella is built
//! from the other points of that same neighbourhood, not from the point's own k = 30 neighbours.
//! Points near the rim of the K-NN ball thus get umbrellas from a one-sided set (fans that reach
//! further inwards than a global triangulation would, and no fans across the rim). Those
//! triangles still have their vertices on the surface and enter with their corrected areas, so
//! the estimate stays consistent; it equals the paper's one when the umbrellas of the rim
//! points are unaffected.

use super::cnc::CncMeasures;
use super::{local, Curvature, Estimator, Neighbourhood, Scratch};
use crate::core::geometry::{dot, tangent_basis, TangentBasis};

/// Label of a Voronoi-cell edge that comes from the bounding square, not from a bisector.
const BOX: usize = usize::MAX;

/// A vertex of the clipped Voronoi cell and the label (neighbour index) of the edge that leaves
/// it.
#[derive(Debug, Clone, Copy)]
struct CellVertex {
    p: [f64; 2],
    edge: usize,
}

/// The estimator's buffers in [`super::Scratch`] (no allocation per point once warm).
#[derive(Default)]
pub struct Buffers {
    /// Neighbours of the current umbrella centre: (squared distance, index, tangent coordinates).
    others: Vec<(f64, usize, [f64; 2])>,
    cell: Vec<CellVertex>,
    clipped: Vec<CellVertex>,
    triangles: Vec<[usize; 3]>,
}

/// Clips the convex polygon `cell` by the half-plane <y | q> <= |q|^2/2 (the side of the
/// bisector of the origin and q that holds the origin); the new edge gets label `label`.
fn clip(cell: &[CellVertex], q: [f64; 2], label: usize, out: &mut Vec<CellVertex>) {
    out.clear();
    let c = 0.5 * (q[0] * q[0] + q[1] * q[1]);
    let side = |p: [f64; 2]| p[0] * q[0] + p[1] * q[1] - c;
    for (i, a) in cell.iter().enumerate() {
        let b = cell[(i + 1) % cell.len()];
        let (fa, fb) = (side(a.p), side(b.p));
        let cut = |fa: f64, fb: f64| {
            let t = fa / (fa - fb);
            [
                a.p[0] + t * (b.p[0] - a.p[0]),
                a.p[1] + t * (b.p[1] - a.p[1]),
            ]
        };
        match (fa <= 0.0, fb <= 0.0) {
            (true, true) => out.push(*a),
            (true, false) => {
                out.push(*a);
                out.push(CellVertex {
                    p: cut(fa, fb),
                    edge: label,
                });
            }
            (false, true) => out.push(CellVertex {
                p: cut(fa, fb),
                edge: a.edge,
            }),
            (false, false) => {}
        }
    }
}

/// Appends to `s.triangles` the Delaunay umbrella of point `c` of `nb` (sorted index triples):
/// the Voronoi cell of `c` among the tangent projections of the other points, clipped by
/// bisectors nearest first; two consecutive bisector edges meet at a Voronoi vertex, the
/// circumcentre of a Delaunay triangle incident to `c`.
fn umbrella(nb: &Neighbourhood<'_>, c: usize, s: &mut Buffers) {
    let TangentBasis { e1, e2 } = tangent_basis(nb.normals[c]);
    let origin = nb.positions[c];
    s.others.clear();
    let mut far: f64 = 0.0;
    for (j, &p) in nb.positions.iter().enumerate() {
        let d = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
        let t = [dot(d, e1), dot(d, e2)];
        let d2 = t[0] * t[0] + t[1] * t[1];
        far = far.max(d2);
        if j != c {
            s.others.push((d2, j, t));
        }
    }
    // Points projecting onto the centre (duplicates) have no bisector.
    let tiny = 1e-20 * far;
    s.others.retain(|o| o.0 > tiny);
    s.others
        .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    // A square far larger than the neighbourhood stands in for the unbounded plane; Voronoi
    // vertices beyond it belong to needle triangles, which are better left out.
    let b = 100.0 * far.sqrt();
    if b.is_nan() || b <= 0.0 {
        return;
    }
    s.cell.clear();
    s.cell
        .extend([[-b, -b], [b, -b], [b, b], [-b, b]].map(|p| CellVertex { p, edge: BOX }));
    for &(d2, j, t) in &s.others {
        // The bisector is at distance |q|/2: once beyond the cell's farthest vertex, no later
        // (farther) point can clip it.
        let reach = s
            .cell
            .iter()
            .map(|v| v.p[0] * v.p[0] + v.p[1] * v.p[1])
            .fold(0.0, f64::max);
        if 0.25 * d2 > reach {
            break;
        }
        clip(&s.cell, t, j, &mut s.clipped);
        std::mem::swap(&mut s.cell, &mut s.clipped);
    }
    let n = s.cell.len();
    for i in 0..n {
        let (a, b) = (s.cell[i].edge, s.cell[(i + 1) % n].edge);
        if a != BOX && b != BOX && a != b {
            let mut t = [c, a, b];
            t.sort_unstable();
            s.triangles.push(t);
        }
    }
}

/// CNC-Delaunay: see the module documentation.
#[derive(Debug, Clone, Copy, Default)]
pub struct CncDelaunay;

impl Estimator for CncDelaunay {
    fn name(&self) -> &'static str {
        "cnc-delaunay"
    }

    fn estimate(&self, nb: &Neighbourhood<'_>, scratch: &mut Scratch) -> Curvature {
        if let Err(f) = local::check(nb, 3) {
            return Curvature::undefined(f);
        }
        let s = &mut scratch.delaunay;
        s.triangles.clear();
        for c in 0..nb.positions.len() {
            umbrella(nb, c, s);
        }
        // A triangle appears in up to three umbrellas: count it once (algorithms.md 4.9).
        s.triangles.sort_unstable();
        s.triangles.dedup();
        let mut m = CncMeasures::default();
        for t in &s.triangles {
            m.add_triangle(t.map(|j| nb.positions[j]), t.map(|j| nb.normals[j]));
        }
        m.finish(nb.normals[0], 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a regular square grid with a jitter, the umbrella of an interior point is its
    /// Delaunay 1-ring: a closed fan of triangles around it.
    #[test]
    fn umbrella_of_interior_point_is_closed_fan() {
        let mut pos = vec![[0.0; 3]];
        let mut k = 0.0;
        for i in -2i32..=2 {
            for j in -2i32..=2 {
                if i != 0 || j != 0 {
                    k += 1.0;
                    pos.push([
                        i as f64 + 0.01 * (k * 0.7f64).sin(),
                        j as f64 + 0.01 * (k * 1.3f64).cos(),
                        0.0,
                    ]);
                }
            }
        }
        let nrm = vec![[0.0, 0.0, 1.0]; pos.len()];
        let nb = Neighbourhood {
            positions: &pos,
            normals: &nrm,
            key: 0,
        };
        let mut s = Buffers::default();
        umbrella(&nb, 0, &mut s);
        // A closed fan without overlaps: the angles at the centre sum to 2 pi, and every
        // neighbour of the fan is shared by exactly two triangles.
        let angle: f64 = s
            .triangles
            .iter()
            .map(|t| {
                let (a, b) = (pos[t[1]], pos[t[2]]);
                (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt()).acos()
            })
            .sum();
        assert!(
            (angle - std::f64::consts::TAU).abs() < 1e-9,
            "{angle} {:?}",
            s.triangles
        );
        assert!(
            s.triangles.len() >= 4
                && s.triangles.len() <= 8
                && s.triangles.iter().all(|t| t[0] == 0)
        );
        for j in 1..pos.len() {
            let uses = s.triangles.iter().filter(|t| t.contains(&j)).count();
            assert!(uses == 0 || uses == 2, "{j}: {uses}");
        }
    }

    use crate::core::estimate::flags;
    use crate::kit::testkit::{self, below, errors, Shape};

    /// algorithms.md 13.8: exact H = 1/r, K = 1/r^2 on a spherical cap with exact normals (1e-9
    /// relative).
    #[test]
    fn sphere_identity() {
        let r = 2.5;
        let (pos, nrm) = testkit::sphere_cap(r, 30);
        let c = testkit::run(&CncDelaunay, &pos, &nrm);
        assert!(
            (c.h * r - 1.0).abs() < 1e-9 && (c.k * r * r - 1.0).abs() < 1e-9,
            "{c:?}"
        );
    }

    /// No published figure for CNC-Delaunay in algorithms.md 14.3 (the paper's plots put it with
    /// the other variants): H bounds are 1.25 x the CNC-Uniform figures (torus K=50 1.38e-3, K=20
    /// 1.07e-3; goursat K=50 3.62e-3, K=20 2.25e-3), on every 5th point to keep the test short (the
    /// umbrellas cost ~60 us per point). Measured k2 errors are larger than the other variants'
    /// (torus K=50 8.1e-3): the umbrella triangles cover the whole K-ball, so the anisotropic
    /// measure sees the normals tilt over a larger area; bound 1.5x measured.
    #[test]
    fn reference_clouds() {
        for (shape, k, uniform) in [
            (Shape::TorusRef, 50, 1.38),
            (Shape::TorusRef, 20, 1.07),
            (Shape::GoursatRef, 50, 3.62),
            (Shape::GoursatRef, 20, 2.25),
        ] {
            let Some(e) = errors(&CncDelaunay, shape, k, 5) else {
                return;
            };
            assert_eq!(e.undefined, 0);
            below(e.h.rms, 1.25e-3 * uniform, &format!("{shape:?} K={k} H"));
        }
        if let Some(e) = errors(&CncDelaunay, Shape::TorusRef, 50, 5) {
            below(e.k2.rms, 1.5 * 8.1e-3, "torus K=50 k2");
        }
    }

    /// Sampled torus (algorithms.md 14.2: CNC RMS H 1.8-2.0e-3, G 1.4-1.7e-3; bounds 2x the top)
    /// and saddle (measured H 0.8e-3, k 2.0e-3 with seed 1; bounds 2x), every 5th point.
    #[test]
    fn sampled_shapes() {
        let e = errors(&CncDelaunay, Shape::Torus, 50, 5).expect("synthetic");
        below(e.h.rms, 4.0e-3, "torus H");
        below(e.k.rms, 3.4e-3, "torus K");
        below(e.d1_deg.rms, 0.6, "torus d1 (deg)");
        let e = errors(&CncDelaunay, Shape::Saddle, 30, 5).expect("synthetic");
        below(e.h.rms, 1.6e-3, "saddle H");
        below(e.k1.rms.max(e.k2.rms), 4.0e-3, "saddle k");
    }

    /// Flips exact, rigid motions to rounding (a Delaunay triangulation does not depend on the
    /// tangent frame), degenerate inputs flagged.
    #[test]
    fn flips_motions_and_degenerate_inputs() {
        testkit::flip_symmetry(&CncDelaunay, 100, 1e-9);
        testkit::motion_invariance(&CncDelaunay, 100, false, 1e-6);
        testkit::motion_invariance(&CncDelaunay, 100, true, 1e-6);
        let r = testkit::degenerate_inputs(&CncDelaunay, true);
        assert!(r[3].flags & flags::UNDEFINED != 0 && r[4].flags & flags::UNDEFINED != 0);
    }
}
