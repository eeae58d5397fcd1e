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

/// In-memory size of one bucketed point, for the budget.
pub const BUCKET_POINT_BYTES: usize = std::mem::size_of::<SourcePoint>() + 8;

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
