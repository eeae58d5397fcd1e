//! A tile's neighbour lists: the k-NN of every point that needs one, in one flat array the
//! caller owns ([`TileBuffers`]), each list marked complete when nothing nearer can lie outside
//! the loaded region, with the normals found right after each list for one fixed k.

use std::sync::atomic::AtomicBool;

use super::*;

/// What the k-NN of one point left in its slot of the tile's flat list array.
#[derive(Clone, Copy, Default)]
pub(super) struct ListInfo {
    /// Entries of the list (0: no list computed for this point).
    pub(super) len: u32,
    /// Whether the list is provably the point's true k-NN (nothing nearer is outside the
    /// loaded region).
    pub(super) complete: bool,
    /// Whether the list's first [`Reach::prefix`] entries are provably the point's true
    /// nearest (always so when the list is complete).
    pub(super) prefix: bool,
}

/// `compute_tile`'s flat neighbour lists and their `ListInfo`, owned by the caller and reused
/// from tile to tile: fresh buffers cost a zeroed page per 4 KiB every tile, and faulting those
/// pages in is a large share of a run's system time (docs/performance.md).
#[derive(Default)]
pub struct TileBuffers {
    pub(super) lists: Vec<u32>,
    pub(super) info: Vec<ListInfo>,
}

/// How far a tile's neighbour lists reach.
#[derive(Clone, Copy)]
pub(super) struct Reach {
    /// Entries per list.
    pub(super) k: usize,
    /// `--radius`, if any.
    pub(super) radius: Option<f64>,
    /// The prefix whose completeness is recorded besides the whole list's (`ListInfo`): the
    /// neighbourhood of the normals under `-k auto`; `k` otherwise.
    pub(super) prefix: usize,
}

/// What a tile's neighbour lists are found in and how far they reach: the loaded points, their
/// index, the cloud's extent (a list is complete when nothing nearer can lie outside the loaded
/// region) and the lists' [`Reach`].
#[derive(Clone, Copy)]
pub(super) struct ListQuery<'a> {
    /// The loaded points (core and halo).
    pub(super) t: &'a TilePoints,
    /// Their k-NN index.
    pub(super) index: &'a NeighbourIndex<'a>,
    /// The x/y extent of the whole cloud.
    pub(super) scene: &'a Rect,
    /// Entries per list, radius and recorded prefix.
    pub(super) reach: Reach,
}

/// The neighbourhood of point `i` into `slot` (its k entries of the flat list array): its k
/// nearest, cut at `radius` when one is given. `scratch` and `list` are the query's buffers.
pub(super) fn knn_into(
    q: &ListQuery<'_>,
    i: usize,
    scratch: &mut KnnScratch,
    list: &mut Vec<u32>,
    slot: &mut [u32],
) -> ListInfo {
    let ListQuery {
        t,
        index,
        scene,
        reach,
    } = *q;
    let far = index.knn(i, reach.k, scratch, list);
    let full = list.len() == reach.k;
    let cut = reach
        .radius
        .is_some_and(|r| index.cut_to_radius(i, r, list));
    slot[..list.len()].copy_from_slice(list);
    let p = t.xyz[i];
    let room = t.region.distance_to_open_side(p[0], p[1], scene);
    // Any point not loaded is strictly farther than `room`. A list cut at the radius, or one
    // with fewer than k points loaded, holds every loaded point within the radius: complete
    // when nothing within the radius can be unloaded (a margin of a few ulps covers the
    // rounding of the squared distances). Otherwise the list is the k nearest loaded points,
    // complete when the farthest of them is within `room` (all inside the radius, if any).
    let within = |r: f64| r * (1.0 + 8.0 * f64::EPSILON) < room;
    let complete = if cut || !full {
        room.is_infinite() || reach.radius.is_some_and(within)
    } else {
        far <= room
    };
    // A prefix of the k nearest is the true nearest of its size when its farthest is within
    // `room` (recomputed here, hence the margin); the whole list's prefix is the list.
    let prefix = complete
        || reach.prefix < reach.k
            && list.get(reach.prefix.wrapping_sub(1)).is_some_and(|&j| {
                let d = sub(t.xyz[j as usize], p);
                within(dot(d, d).sqrt())
            });
    ListInfo {
        len: list.len() as u32,
        complete,
        prefix,
    }
}

/// Where the list pass also writes the normal of each point it lists ([`normal_of`] over the
/// whole list, found while the list's points are in cache): one fixed k.
pub(super) struct ListNormals<'a> {
    pub(super) p: &'a ComputeParams<'a>,
    /// Indexed like the tile's points.
    pub(super) out: &'a mut [Option<V3>],
}

/// Points per task of [`lists_for`].
pub(super) const LIST_CHUNK: usize = 1024;

/// The lists of the points `which` marks that have none yet, into `bufs`. Each task takes
/// [`LIST_CHUNK`] consecutive points and queries them in the index's order
/// ([`NeighbourIndex::query_key`]: by grid cell), so that consecutive queries share the block
/// the grid gathers per cell: in the tile's Morton order a block served fewer than 3 queries.
/// The lists are exact whatever the order of the queries.
pub(super) fn lists_for(
    q: &ListQuery<'_>,
    bufs: &mut TileBuffers,
    normals: Option<&mut ListNormals<'_>>,
    which: &[bool],
    cancel: &AtomicBool,
) {
    let (t, index, k) = (q.t, q.index, q.reach.k);
    let scratch = || {
        let todo: Vec<(u64, u32)> = Vec::with_capacity(LIST_CHUNK);
        (
            KnnScratch::default(),
            Vec::with_capacity(k),
            todo,
            Vec::new(),
        )
    };
    let TileBuffers { lists, info } = bufs;
    let chunks = info.len().div_ceil(LIST_CHUNK);
    // The normals each task finds (none: an empty slice per task).
    let (p, mut outs): (_, Vec<&mut [Option<V3>]>) = match normals {
        Some(ListNormals { p, out }) => (Some(*p), out.chunks_mut(LIST_CHUNK).collect()),
        None => (None, (0..chunks).map(|_| Default::default()).collect()),
    };
    lists
        .par_chunks_mut(LIST_CHUNK * k)
        .zip(info.par_chunks_mut(LIST_CHUNK))
        .zip(outs.par_iter_mut())
        .enumerate()
        .for_each_init(
            scratch,
            |(s, list, todo, spare), (c, ((slots, infos), nrm))| {
                let first = c * LIST_CHUNK;
                todo.clear();
                todo.extend(
                    (0..infos.len())
                        .filter(|&o| infos[o].len == 0 && which[first + o])
                        .map(|o| (index.query_key(first + o), o as u32)),
                );
                crate::core::radix::sort_by_key(todo, spare);
                for &(_, o) in todo.iter() {
                    if cancel.load(Ordering::Relaxed) {
                        return;
                    }
                    let (o, i) = (o as usize, first + o as usize);
                    let slot = &mut slots[o * k..(o + 1) * k];
                    infos[o] = knn_into(q, i, s, list, slot);
                    // The normal now, while the list's points are in cache.
                    if let (Some(p), Some(n)) = (p, nrm.get_mut(o)) {
                        *n = normal_of(t, p, &slot[..infos[o].len as usize], k);
                    }
                }
            },
        );
}

/// The points within the first `prefix` entries of the lists of the points `from` marks.
pub(super) fn mark(bufs: &TileBuffers, k: usize, from: &[bool], prefix: usize) -> Vec<bool> {
    let marked: Vec<AtomicBool> = from.iter().map(|_| AtomicBool::new(false)).collect();
    (0..from.len()).into_par_iter().for_each(|i| {
        if from[i] {
            let l = bufs.list(i, k);
            for &j in &l[..l.len().min(prefix)] {
                marked[j as usize].store(true, Ordering::Relaxed);
            }
        }
    });
    marked.into_iter().map(AtomicBool::into_inner).collect()
}

/// Steps 1 and 2: the neighbour lists of the core points, then level by level of the points
/// the previous level's lists reach (the first `levels[l]` entries of each), into `bufs`
/// (point i: `lists[i k ..][..len]`). One fixed k needs one level (the neighbours, whose
/// normals are used); `-k auto` two (auto.rs). With `normals`, step 3 too, point by point.
pub(super) fn neighbour_lists(
    q: &ListQuery<'_>,
    levels: &[usize],
    bufs: &mut TileBuffers,
    mut normals: Option<ListNormals<'_>>,
    cancel: &AtomicBool,
) {
    let (t, reach) = (q.t, q.reach);
    let n = t.xyz.len();
    // Grown, never cleared: a list is read only as far as its info's length, which this tile's
    // query wrote, so zeroing the whole buffer each tile would be work for nothing.
    if bufs.lists.len() < n * reach.k {
        bufs.lists.resize(n * reach.k, 0);
    }
    bufs.info.clear();
    bufs.info.resize(n, ListInfo::default());
    let mut level: Vec<bool> = (0..n).map(|i| i < t.n_core).collect();
    // The core level, then one level per prefix, each marked from the one before.
    for prefix in std::iter::once(None).chain(levels.iter().map(Some)) {
        if let Some(&prefix) = prefix {
            level = mark(bufs, reach.k, &level, prefix);
        }
        lists_for(q, bufs, normals.as_mut(), &level, cancel);
    }
}

impl TileBuffers {
    /// The neighbour list of point `i` (empty if none was computed).
    pub(super) fn list(&self, i: usize, k: usize) -> &[u32] {
        &self.lists[i * k..i * k + self.info[i].len as usize]
    }

    /// Whether point `i`'s estimate is exact: its list is complete, and so is the normal
    /// prefix ([`ListInfo::prefix`]) of each of its neighbours, the whole list for one k
    /// (otherwise a core point is retried with a wider halo).
    pub(super) fn exact(&self, i: usize, k: usize) -> bool {
        self.info[i].complete
            && self.list(i, k).iter().all(|&j| {
                let lj = self.info[j as usize];
                lj.len > 0 && lj.prefix
            })
    }
}
