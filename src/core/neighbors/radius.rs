//! Radius neighbourhoods (`--radius R`): the point itself and every point within distance R,
//! at most `cap` of them, the nearest by the k-NN ranking ([`NeighbourIndex::knn`]: exact f64
//! squared distance, then position rank). Found as the `cap` nearest, cut at R: the same list
//! in every tile, thread and input order, since both the ranking and the cut depend on the
//! points alone.

use super::NeighbourIndex;

impl NeighbourIndex<'_> {
    /// Cuts `list`, the k-NN list of point `i` as [`NeighbourIndex::knn`] wrote it (`i` first,
    /// then by increasing rank), to the points within distance `r` of point `i` (squared f64
    /// distance <= r * r). Returns whether any entry was cut: then the list holds every loaded
    /// point within `r` (up to the k-NN's count), and it is the true neighbourhood when no
    /// point within `r` can be missing from the loaded region.
    pub fn cut_to_radius(&self, i: usize, r: f64, list: &mut Vec<u32>) -> bool {
        let q = self.xyz[i];
        let r2 = r * r;
        let first_out = list
            .iter()
            .skip(1)
            .position(|&j| self.dist2(q, j as usize) > r2)
            .map(|p| p + 1);
        match first_out {
            Some(p) => {
                list.truncate(p);
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::KnnScratch;
    use super::*;
    use crate::core::geometry::{sub, V3};

    /// Brute force: self first, then every other point within `r` by (squared distance, x, y,
    /// z, id), the first `cap - 1` of them.
    fn brute(xyz: &[V3], ids: &[u64], i: usize, r: f64, cap: usize) -> Vec<u32> {
        let d2 = |j: usize| {
            let d = sub(xyz[j], xyz[i]);
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        };
        let mut v: Vec<(f64, [f64; 3], u64, u32)> = (0..xyz.len())
            .filter(|&j| j != i && d2(j) <= r * r)
            .map(|j| (d2(j), xyz[j].map(|c| c + 0.0), ids[j], j as u32))
            .collect();
        v.sort_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1[0].total_cmp(&b.1[0]))
                .then(a.1[1].total_cmp(&b.1[1]))
                .then(a.1[2].total_cmp(&b.1[2]))
                .then(a.2.cmp(&b.2))
        });
        std::iter::once(i as u32)
            .chain(v.into_iter().take(cap - 1).map(|t| t.3))
            .collect()
    }

    /// On a quantized grid far from the origin (many exact ties in distance, some exact
    /// duplicates, a sparse outlier), the cut list equals brute force for radii that cut
    /// before the cap, at it and past it; and the cut is reported exactly when some of the
    /// cap nearest lie beyond R.
    #[test]
    fn a_radius_cut_list_is_brute_force() {
        let mut xyz = Vec::new();
        let mut rng = crate::core::rng::Rng::new(7);
        for gx in 0..24 {
            for gy in 0..24 {
                let z = 80.0 + ((rng.next_u64() % 8) as f64) * 0.25;
                let p = [
                    400_000.0 + gx as f64 * 0.5,
                    6_000_000.0 + gy as f64 * 0.5,
                    z,
                ];
                xyz.push(p);
                if rng.next_u64().is_multiple_of(9) {
                    xyz.push(p);
                }
            }
        }
        xyz.push([400_050.0, 6_000_050.0, 80.0]);
        let ids: Vec<u64> = (0..xyz.len() as u64).map(|i| i * 3 + 1).collect();
        let mut scratch = KnnScratch::default();
        let mut list = Vec::new();
        for cap in [6, 30, 100] {
            let index = NeighbourIndex::build(&xyz, &ids, cap).expect("index");
            for r in [0.3, 0.5, 1.0, 1.6, 3.0] {
                for i in 0..xyz.len() {
                    index.knn(i, cap, &mut scratch, &mut list);
                    let full = list.len();
                    let cut = index.cut_to_radius(i, r, &mut list);
                    assert_eq!(
                        list,
                        brute(&xyz, &ids, i, r, cap),
                        "point {i} r {r} cap {cap}"
                    );
                    assert_eq!(cut, list.len() < full, "point {i} r {r} cap {cap}");
                }
            }
        }
    }
}
