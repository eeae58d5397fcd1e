//! A point as the engine sees it, whatever file it came from: its global id (position in the
//! scene's file order), coordinates in f64 and the file's normal if any.

/// One point: original index, coordinates, and the file's normal if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourcePoint {
    /// Index of the point in its file (file order); the scene-wide id once the scan adds the
    /// earlier inputs' counts.
    pub id: u64,
    /// Coordinates in file units.
    pub xyz: [f64; 3],
    /// The normal stored in the file, if any.
    pub normal: Option<[f64; 3]>,
}

/// In-memory size of one bucketed point ([`Points`] without file normals: id and position),
/// for the budget, with 8 bytes for the growth of its columns.
pub const BUCKET_POINT_BYTES: usize = 8 + 24 + 8;

/// Points as columns (a bucket's): ids, positions, and the file's normals, kept only from the
/// first point that has one. LIDAR files rarely carry normals: without them a point takes 32
/// bytes, not the 64 of a [`SourcePoint`] (whose `Option` normal is 32 bytes even when None),
/// which halves the buckets' share of the peak memory and the pages the scan faults in
/// (docs/performance.md).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Points {
    ids: Vec<u64>,
    xyz: Vec<[f64; 3]>,
    /// Empty while no point has a normal ([`push_normal`]).
    normals: Vec<Option<[f64; 3]>>,
}

/// Appends `n`, the normal of the point at `at`, to `normals`, a column that stays empty while
/// every normal is None (then filled with None up to `at` when the first one comes).
pub fn push_normal(normals: &mut Vec<Option<[f64; 3]>>, at: usize, n: Option<[f64; 3]>) {
    if n.is_some() && normals.len() < at {
        normals.resize(at, None);
    }
    if !normals.is_empty() || n.is_some() {
        normals.push(n);
    }
}

impl Points {
    /// Appends a point.
    pub fn push(&mut self, p: &SourcePoint) {
        push_normal(&mut self.normals, self.ids.len(), p.normal);
        self.ids.push(p.id);
        self.xyz.push(p.xyz);
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether there is no point.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The positions, in order.
    pub fn xyz(&self) -> &[[f64; 3]] {
        &self.xyz
    }

    /// The ids, in order.
    pub fn ids(&self) -> &[u64] {
        &self.ids
    }

    /// The file's normal of point `i`, if it has one.
    pub fn normal(&self, i: usize) -> Option<[f64; 3]> {
        self.normals.get(i).copied().flatten()
    }

    /// Point `i` (which must be below `len`).
    pub fn get(&self, i: usize) -> SourcePoint {
        SourcePoint {
            id: self.ids[i],
            xyz: self.xyz[i],
            normal: self.normal(i),
        }
    }

    /// The points, in order.
    pub fn iter(&self) -> impl Iterator<Item = SourcePoint> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// Appends every point of `other`.
    pub fn extend_from(&mut self, other: &Points) {
        if !other.normals.is_empty() || !self.normals.is_empty() {
            self.normals.resize(self.len(), None);
            self.normals.extend(other.iter().map(|p| p.normal));
        }
        self.ids.extend_from_slice(&other.ids);
        self.xyz.extend_from_slice(&other.xyz);
    }

    /// Appends points given as columns: ids, positions and normals (empty when no point has
    /// one; else one a point).
    pub fn append_columns(&mut self, ids: &[u64], xyz: &[[f64; 3]], normals: &[Option<[f64; 3]>]) {
        debug_assert!(ids.len() == xyz.len() && (normals.is_empty() || normals.len() == ids.len()));
        if !normals.is_empty() || !self.normals.is_empty() {
            self.normals.resize(self.len(), None);
            match normals.is_empty() {
                true => self.normals.resize(self.len() + ids.len(), None),
                false => self.normals.extend_from_slice(normals),
            }
        }
        self.ids.extend_from_slice(ids);
        self.xyz.extend_from_slice(xyz);
    }

    /// Bytes the columns hold on the heap (their capacities), for the memory budget.
    pub fn heap_bytes(&self) -> usize {
        self.ids.capacity() * 8 + self.xyz.capacity() * 24 + self.normals.capacity() * 32
    }
}

impl FromIterator<SourcePoint> for Points {
    fn from_iter<I: IntoIterator<Item = SourcePoint>>(iter: I) -> Self {
        let mut out = Points::default();
        for p in iter {
            out.push(&p);
        }
        out
    }
}

/// The order of two positions that ties are broken by, so that results depend on the point set
/// and not on the order of the records: x, then y, then z, each exactly (`total_cmp` after
/// `+ 0.0`, which makes -0 and +0 one value). The same for two points in any tile, so a point
/// in several tiles' halos compares the same in each. Equal only for exact duplicates, which
/// are then ordered by original id ([`cmp_point`]).
#[inline]
pub fn cmp_position(a: &[f64; 3], b: &[f64; 3]) -> std::cmp::Ordering {
    let c = |i: usize| (a[i] + 0.0).total_cmp(&(b[i] + 0.0));
    c(0).then_with(|| c(1)).then_with(|| c(2))
}

/// The total order of points: by position ([`cmp_position`]), then by original id between
/// exact duplicates (geometrically interchangeable, so which comes first changes no value
/// computed from coordinates).
#[inline]
pub fn cmp_point(a: (&[f64; 3], u64), b: (&[f64; 3], u64)) -> std::cmp::Ordering {
    cmp_position(a.0, b.0).then(a.1.cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(id: u64, normal: Option<[f64; 3]>) -> SourcePoint {
        SourcePoint {
            id,
            xyz: [id as f64, -(id as f64), 0.5],
            normal,
        }
    }

    /// The columns give back every point as pushed, the normal column kept only from the first
    /// normal on, and appending columns with and without normals keeps each point's own.
    #[test]
    fn points_give_back_what_was_pushed() {
        let plain: Vec<SourcePoint> = (0..5).map(|i| p(i, None)).collect();
        let mixed: Vec<SourcePoint> = (5..9)
            .map(|i| p(i, (i % 2 == 0).then_some([0.0, 0.6, 0.8])))
            .collect();
        let a: Points = plain.iter().copied().collect();
        // Without normals no normal column is allocated: 32 bytes a point and the growth.
        assert_eq!(a.normals.capacity(), 0);
        assert!(a.heap_bytes() >= 32 * a.len());
        let b: Points = mixed.iter().copied().collect();
        assert_eq!(b.normals.len(), b.len());
        assert!(b.heap_bytes() >= 64 * b.len());
        assert_eq!(b.normal(0), None);
        assert_eq!(b.normal(1), Some([0.0, 0.6, 0.8]));
        for (x, y) in [(&a, &b), (&b, &a)] {
            let mut joined = x.clone();
            joined.extend_from(y);
            let want: Vec<SourcePoint> = x.iter().chain(y.iter()).collect();
            assert_eq!(joined.iter().collect::<Vec<_>>(), want);
            let pushed: Points = want.iter().copied().collect();
            assert_eq!(pushed.iter().collect::<Vec<_>>(), want);
        }
        assert_eq!(b.get(1), mixed[1]);
        assert_eq!(b.ids(), &[5, 6, 7, 8]);
        assert_eq!(b.xyz()[3], [8.0, -8.0, 0.5]);
    }
}
