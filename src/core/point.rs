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
