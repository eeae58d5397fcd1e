//! Orientation of PCA normals beyond the per-point rules of [`crate::core::normals::orient`]:
//! `outward` (away from a centre, for closed star-shaped objects) and `propagate` (a consistent
//! orientation by propagation over the neighbour graph, Hoppe et al. 1992), plus the pieces that
//! make propagation work tile by tile in the out-of-core engine. Pure: no I/O, no threads.
//!
//! # Propagation (one set of points in memory)
//!
//! [`propagate`] builds the symmetric k-NN graph (an edge i–j when j is in the list of i or i in
//! the list of j), weights each edge `1 - |<n_i, n_j>|` (nearly parallel normals are cheap), and
//! grows a minimum spanning tree of each connected component from a seed with Prim's algorithm,
//! flipping every point it reaches to agree with its tree parent (`<n_child, n_parent> >= 0`).
//! The seed of a component is its point farthest from a centre (the component's centroid, or a
//! given point such as the cloud's centroid), oriented away from that centre: on a closed
//! object the farthest point is always on the convex hull, where outward is unambiguous.
//! Points without a normal (`None`: degenerate neighbourhoods) are not in the graph.
//! Cost: O(N k log N) time; memory: the reverse adjacency (N k `u32`) and a few words per point.
//!
//! # Tiled runs
//!
//! A tile holds core points plus a halo. Orientation stays consistent across tiles in three steps:
//!
//! 1. **Per tile.** After the PCA normals of every loaded point with a neighbour list (core and
//!    halo) are computed, [`propagate`] runs over the tile's k-NN lists with
//!    [`Seed::OutwardFrom`]`(global centroid)` (the centroid is accumulated during the plan
//!    pass with [`Centroid`]). Each connected component `c` of tile `t` becomes a *patch* (an id
//!    the engine assigns, e.g. a running counter over tile passes, retries included). The tile
//!    applies its flips *before* the estimator runs, so the tile's curvatures are consistent with
//!    its (possibly globally wrong) patch orientation. The tile reports, beside its results:
//!    - one [`PatchAnchor`] per patch: its seed, the seed's squared distance from the global
//!      centroid and the seed's id ([`Propagation::anchor`]);
//!    - one [`SharedNormal`] (`id`, patch, oriented normal) per loaded point that another pass
//!      also loads: every loaded point within the initial halo width of the core rectangle's
//!      edge (inside or outside it), and in a wider-halo retry pass every loaded point (its
//!      points were oriented by the first pass of the same tile or by its neighbours);
//!    - and, with each point result, its patch.
//!
//!    [`orient_tile`] does all of this for one tile.
//! 2. **Across tiles.** [`votes_from_shared`] turns the shared normals into agreement votes
//!    between patches (the same point oriented by two patches: same sign or not), and
//!    [`patch_signs`] solves one sign per patch: in each connected component of the patch graph,
//!    the patch holding the anchor farthest from the centroid keeps (or takes) the outward sign,
//!    and the others follow a maximum spanning tree of the vote margins.
//! 3. **At assemble time** every result of a flipped patch is negated with [`flip_curvature`]:
//!    the normal flips, `H' = -H`, `K' = K`, and the principal curvatures swap roles,
//!    `k1' = -k2`, `k2' = -k1` (k1 stays the smaller), with their directions `d1' = d2`,
//!    `d2' = d1` (which keeps `d1 x d2 = n`).
//!
//! # Scans bigger than memory
//!
//! Only the patch tables are global: one anchor and one sign per patch (a few per tile), and the
//! vote margins per pair of adjacent patches. The shared normals are proportional to the halo
//! bands, not to the cloud; they can be reduced to votes as soon as every tile that loads a given
//! point has run (or be spilled to the work directory and sorted by id). Nothing else of a tile
//! outlives it. The result is the same orientation a single in-memory propagation would give
//! wherever the tiles agree; where the surface's neighbour graph is connected only through
//! another tile's region, the votes carry the orientation across; a component that no tile shares
//! with any other is oriented by its own outward seed.
//!
//! # Limits
//!
//! The global sign comes from the outward rule at the point farthest from the centroid: right
//! for objects, arbitrary for open surfaces such as terrain, where `up` or a viewpoint is the
//! rule to use. Normals read from the file are not PCA normals and must not be passed to
//! [`propagate`] (it would flip them). Propagation can go wrong across sharp creases and thin
//! sheets closer than the neighbour spacing (the k-NN graph links both sides).

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};

use crate::core::estimate::{Curvature, Extra};
use crate::core::geometry::{add, dot, scale, sub, V3};
use crate::core::normals::{orient, Orientation};

/// `n` flipped if needed so that it points away from `centre` at position `p`:
/// `<n, p - centre> >= 0`. A normal exactly orthogonal to `p - centre` (or `p == centre`) is
/// oriented by the sign of its first non-zero component, the tie rule of
/// [`crate::core::normals::orient`].
pub fn orient_outward(n: V3, p: V3, centre: V3) -> V3 {
    orient(n, p, Orientation::Outward(centre))
}

/// A running centroid of many points (streaming, mergeable), accumulated relative to the first
/// point so that UTM-sized coordinates keep their precision.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Centroid {
    origin: Option<V3>,
    sum: V3,
    n: u64,
}

impl Centroid {
    /// Adds one point.
    pub fn add(&mut self, p: V3) {
        let o = *self.origin.get_or_insert(p);
        self.sum = add(self.sum, sub(p, o));
        self.n += 1;
    }

    /// Adds every point of `other` (e.g. the centroid of another chunk).
    pub fn merge(&mut self, other: &Centroid) {
        let Some(ob) = other.origin else {
            return;
        };
        let o = *self.origin.get_or_insert(ob);
        self.sum = add(self.sum, add(other.sum, scale(sub(ob, o), other.n as f64)));
        self.n += other.n;
    }

    /// The centroid, or None when no point was added.
    pub fn get(&self) -> Option<V3> {
        let o = self.origin?;
        Some(add(o, scale(self.sum, 1.0 / self.n as f64)))
    }
}

/// How [`propagate`] seeds each connected component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Seed {
    /// The component's point farthest from the component's own centroid, oriented away from it.
    /// For a whole object in memory.
    Outward,
    /// The component's point farthest from this centre, oriented away from it. For tiles: the
    /// centroid of the whole cloud, so that seeds of different tiles compare (see
    /// [`patch_signs`]).
    OutwardFrom(V3),
}

/// One connected component of the neighbour graph, as [`propagate`] oriented it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// The seed (local index).
    pub seed: u32,
    /// Squared distance of the seed from the centre it was chosen against.
    pub dist2: f64,
    /// Number of points.
    pub size: u32,
}

/// What [`propagate`] decided: which normals to flip, and the components.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Propagation {
    /// Per point: negate its normal. False for points without a normal.
    pub flip: Vec<bool>,
    /// Per point: its component (index into `components`), [`Propagation::NONE`] for points
    /// without a normal.
    pub component: Vec<u32>,
    /// The components, in order of their smallest point index.
    pub components: Vec<Component>,
}

impl Propagation {
    /// The component of a point without a normal.
    pub const NONE: u32 = u32::MAX;

    /// Negates the flipped normals in place.
    pub fn apply(&self, normals: &mut [Option<V3>]) {
        for (n, &f) in normals.iter_mut().zip(&self.flip) {
            if let (Some(v), true) = (n.as_mut(), f) {
                *v = scale(*v, -1.0);
            }
        }
    }

    /// The anchor of component `c` as patch `patch`, for [`patch_signs`]: `ids` are the
    /// original ids of the points (the same slice the neighbour index was built with). The seed
    /// was oriented away from the centre, so `outward` is true.
    pub fn anchor(&self, c: usize, patch: u32, ids: &[u64]) -> PatchAnchor {
        let comp = self.components[c];
        PatchAnchor {
            patch,
            dist2: comp.dist2,
            id: ids[comp.seed as usize],
            outward: true,
        }
    }
}

/// The reverse adjacency of k-NN lists in compressed rows: the points whose lists hold `j` are
/// `from[start[j]..start[j + 1]]`.
struct InLists {
    start: Vec<usize>,
    from: Vec<u32>,
}

impl InLists {
    fn new<L: AsRef<[u32]>>(n: usize, knn: &[L], live: &[bool]) -> Self {
        let mut start = vec![0usize; n + 1];
        for (i, l) in knn.iter().take(n).enumerate().filter(|(i, _)| live[*i]) {
            for &j in l.as_ref() {
                let j = j as usize;
                if j != i && live[j] {
                    start[j + 1] += 1;
                }
            }
        }
        for j in 0..n {
            start[j + 1] += start[j];
        }
        let mut fill = start.clone();
        let mut from = vec![0u32; start[n]];
        for (i, l) in knn.iter().take(n).enumerate().filter(|(i, _)| live[*i]) {
            for &j in l.as_ref() {
                let j = j as usize;
                if j != i && live[j] {
                    from[fill[j]] = i as u32;
                    fill[j] += 1;
                }
            }
        }
        InLists { start, from }
    }

    /// The neighbours of `i` in the symmetric graph (possibly with repeats): its own list, then
    /// the points whose lists hold it.
    fn neighbours<'s, L: AsRef<[u32]>>(
        &'s self,
        knn: &'s [L],
        i: usize,
    ) -> impl Iterator<Item = usize> + 's {
        let own = knn.get(i).map(|l| l.as_ref()).unwrap_or(&[]);
        own.iter()
            .chain(&self.from[self.start[i]..self.start[i + 1]])
            .map(|&j| j as usize)
    }
}

/// Orients `normals` consistently by propagation over the symmetric k-NN graph (see the module
/// documentation). `xyz` are the points, `knn[i]` the neighbour list of point `i` (local
/// indices; `i` itself may appear and is ignored; an empty list for points without one, and
/// `knn` may be shorter than `xyz`; entries past `xyz.len()` are ignored), `normals[i]` the
/// unoriented unit normal or None.
/// Returns the flips to apply ([`Propagation::apply`]) and the components with their seeds.
/// Deterministic: depends only on the inputs and their order.
///
/// # Panics
/// When `normals` and `xyz` differ in length, or a list holds an index out of range.
pub fn propagate<L: AsRef<[u32]>>(
    xyz: &[V3],
    knn: &[L],
    normals: &[Option<V3>],
    seed: Seed,
) -> Propagation {
    let n = xyz.len();
    assert_eq!(normals.len(), n, "one normal slot per point");
    let live: Vec<bool> = normals.iter().map(Option::is_some).collect();
    let rev = InLists::new(n, knn, &live);
    let mut out = Propagation {
        flip: vec![false; n],
        component: vec![Propagation::NONE; n],
        components: Vec::new(),
    };
    // 1. Components by breadth-first search, in order of their smallest index.
    let mut queue: Vec<u32> = Vec::new();
    let mut members: Vec<u32> = Vec::new();
    // Per component: offsets of its members in `members`.
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for s in 0..n {
        if !live[s] || out.component[s] != Propagation::NONE {
            continue;
        }
        let c = spans.len() as u32;
        let first = members.len();
        out.component[s] = c;
        queue.clear();
        queue.push(s as u32);
        let mut head = 0;
        while head < queue.len() {
            let i = queue[head] as usize;
            head += 1;
            members.push(i as u32);
            for j in rev.neighbours(knn, i) {
                if live[j] && out.component[j] == Propagation::NONE {
                    out.component[j] = c;
                    queue.push(j as u32);
                }
            }
        }
        spans.push((first, members.len()));
    }
    // 2. Seeds: farthest from the centre (ties: smaller index), oriented away from it.
    for &(a, b) in &spans {
        let pts = &members[a..b];
        let centre = match seed {
            Seed::OutwardFrom(c) => c,
            Seed::Outward => {
                let mut acc = Centroid::default();
                for &i in pts {
                    acc.add(xyz[i as usize]);
                }
                acc.get().unwrap_or(xyz[pts[0] as usize])
            }
        };
        let (mut best, mut best_d) = (pts[0], -1.0);
        for &i in pts {
            let d = sub(xyz[i as usize], centre);
            let d2 = dot(d, d);
            if d2 > best_d || (d2 == best_d && i < best) {
                (best, best_d) = (i, d2);
            }
        }
        let s = best as usize;
        if let Some(ns) = normals[s] {
            out.flip[s] = dot(orient_outward(ns, xyz[s], centre), ns) < 0.0;
        }
        out.components.push(Component {
            seed: best,
            dist2: best_d,
            size: pts.len() as u32,
        });
    }
    drop(members);
    // 3. Prim's minimum spanning tree from each seed; each reached point agrees with its parent.
    let mut done = vec![false; n];
    let mut best = vec![f64::INFINITY; n];
    // Min-heap of (weight bits, child, parent): weights are in [0, 1], so their bits order them.
    let mut heap: BinaryHeap<Reverse<(u64, u32, u32)>> = BinaryHeap::new();
    let weight = |a: V3, b: V3| (1.0 - dot(a, b).abs()).max(0.0);
    for comp in &out.components {
        let s = comp.seed as usize;
        done[s] = true;
        let mut reached = s;
        loop {
            let nr = normals[reached].unwrap_or_default();
            for j in rev.neighbours(knn, reached) {
                if let (Some(nj), false) = (normals[j], done[j]) {
                    let w = weight(nr, nj);
                    if w < best[j] {
                        best[j] = w;
                        heap.push(Reverse((w.to_bits(), j as u32, reached as u32)));
                    }
                }
            }
            let next = loop {
                match heap.pop() {
                    Some(Reverse((_, j, _))) if done[j as usize] => continue,
                    other => break other,
                }
            };
            let Some(Reverse((_, j, parent))) = next else {
                break;
            };
            let (j, parent) = (j as usize, parent as usize);
            done[j] = true;
            let np = normals[parent].unwrap_or_default();
            let nj = normals[j].unwrap_or_default();
            out.flip[j] = (dot(nj, np) < 0.0) != out.flip[parent];
            reached = j;
        }
    }
    out
}

/// What one tile contributes to the cross-tile step, from [`orient_tile`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TileOrientation {
    /// The first patch id of the tile: component `c` is patch `first_patch + c`.
    pub first_patch: u32,
    /// Per loaded point: its component, [`Propagation::NONE`] without a normal.
    pub component: Vec<u32>,
    /// One anchor per component (its seed, against the common centre).
    pub anchors: Vec<PatchAnchor>,
    /// The oriented normals of the points the caller marked as shared with other tiles.
    pub shared: Vec<SharedNormal>,
}

impl TileOrientation {
    /// Number of patches (components) of the tile: the next tile's `first_patch` is
    /// `first_patch + n_patches()`.
    pub fn n_patches(&self) -> u32 {
        self.anchors.len() as u32
    }

    /// The patch of loaded point `i`, None when it has no normal.
    pub fn patch(&self, i: usize) -> Option<u32> {
        let c = *self.component.get(i)?;
        (c != Propagation::NONE).then(|| self.first_patch + c)
    }
}

/// The per-tile step of a tiled propagation (see the module documentation): orients the
/// tile's `normals` in place by [`propagate`] seeded with [`Seed::OutwardFrom`]`(centre)`
/// (`centre`: the centroid of the whole cloud), numbers its components as patches from
/// `first_patch`, and collects their anchors and the oriented normals of the loaded points for
/// which `is_shared(i)` holds (points another tile also loads: the halo, and the core points
/// within the halo width of the core's edge). `xyz`, `ids`, `knn` and `normals` are the tile's
/// loaded points (core and halo) as for [`propagate`].
pub fn orient_tile<L: AsRef<[u32]>>(
    xyz: &[V3],
    ids: &[u64],
    knn: &[L],
    normals: &mut [Option<V3>],
    centre: V3,
    first_patch: u32,
    is_shared: impl Fn(usize) -> bool,
) -> TileOrientation {
    let prop = propagate(xyz, knn, normals, Seed::OutwardFrom(centre));
    prop.apply(normals);
    let anchors = (0..prop.components.len())
        .map(|c| prop.anchor(c, first_patch + c as u32, ids))
        .collect();
    let shared = normals
        .iter()
        .enumerate()
        .filter_map(|(i, n)| {
            let n = (*n)?;
            is_shared(i).then(|| SharedNormal {
                id: ids[i],
                patch: first_patch + prop.component[i],
                normal: n,
            })
        })
        .collect();
    TileOrientation {
        first_patch,
        component: prop.component,
        anchors,
        shared,
    }
}

/// Where a patch's orientation is known from its seed: a candidate for the reference of its
/// connected group of patches in [`patch_signs`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchAnchor {
    /// The patch.
    pub patch: u32,
    /// Squared distance of the anchor point from the common centre (the global centroid).
    pub dist2: f64,
    /// Original id of the anchor point (breaks ties).
    pub id: u64,
    /// Whether the patch's normal at the anchor points away from the centre.
    pub outward: bool,
}

/// A point's oriented normal as one patch saw it, for [`votes_from_shared`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedNormal {
    /// Original point id.
    pub id: u64,
    /// The patch that oriented it.
    pub patch: u32,
    /// Its oriented normal in that patch.
    pub normal: V3,
}

/// Votes between two patches from the points both oriented.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatchVote {
    /// One patch.
    pub a: u32,
    /// The other patch.
    pub b: u32,
    /// Points whose two normals agree (`<n_a, n_b> > 0`).
    pub agree: u64,
    /// Points whose two normals disagree (`<n_a, n_b> < 0`).
    pub disagree: u64,
}

/// The agreement votes between patches from the normals they gave to the same points: for each
/// point id seen by several patches, one vote per pair of patches. Sorts `entries` by (id, patch);
/// returns one vote per pair (a < b), sorted. Votes from separate batches may simply be
/// concatenated: [`patch_signs`] adds up repeated pairs.
pub fn votes_from_shared(entries: &mut [SharedNormal]) -> Vec<PatchVote> {
    entries.sort_unstable_by(|x, y| x.id.cmp(&y.id).then(x.patch.cmp(&y.patch)));
    let mut tally: BTreeMap<(u32, u32), (u64, u64)> = BTreeMap::new();
    for group in entries.chunk_by(|x, y| x.id == y.id) {
        for (i, x) in group.iter().enumerate() {
            for y in &group[i + 1..] {
                if x.patch == y.patch {
                    continue;
                }
                let d = dot(x.normal, y.normal);
                let t = tally.entry((x.patch, y.patch)).or_default();
                if d > 0.0 {
                    t.0 += 1;
                } else if d < 0.0 {
                    t.1 += 1;
                }
            }
        }
    }
    tally
        .into_iter()
        .map(|((a, b), (agree, disagree))| PatchVote {
            a,
            b,
            agree,
            disagree,
        })
        .collect()
}

/// One sign per patch, from [`patch_signs`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PatchSigns {
    /// Per patch: negate its results.
    pub flip: Vec<bool>,
    /// Votes the solution contradicts (inconsistencies between patches; 0 when all agree).
    pub contradicted: u64,
    /// All votes.
    pub votes: u64,
}

/// Solves one sign per patch (`0..n_patches`) from the votes between patches and their anchors.
/// In each connected group of patches (linked by a non-tied vote margin), the anchor with the
/// largest `dist2` (ties: smaller id, then smaller patch) fixes its patch's sign (flip it unless
/// `outward`); the other patches follow a maximum spanning tree of the margins
/// `|agree - disagree|` from there (ties: smaller patch index), each taking its tree parent's
/// sign when its votes mostly agree and the opposite otherwise. A group without an anchor keeps
/// its reference patch (the smallest index) as it is. Votes and anchors naming patches out of
/// range are ignored. Deterministic, and independent of the order of `votes` and `anchors`.
pub fn patch_signs(n_patches: usize, votes: &[PatchVote], anchors: &[PatchAnchor]) -> PatchSigns {
    let np = n_patches;
    let mut margin: BTreeMap<(u32, u32), (u64, u64)> = BTreeMap::new();
    for v in votes {
        if v.a == v.b || v.a as usize >= np || v.b as usize >= np {
            continue;
        }
        let (key, (ag, dis)) = if v.a < v.b {
            ((v.a, v.b), (v.agree, v.disagree))
        } else {
            ((v.b, v.a), (v.agree, v.disagree))
        };
        let t = margin.entry(key).or_default();
        t.0 += ag;
        t.1 += dis;
    }
    // Adjacency: (neighbour, |margin|, opposite sign).
    let mut adj: Vec<Vec<(u32, u64, bool)>> = vec![Vec::new(); np];
    for (&(a, b), &(ag, dis)) in &margin {
        if ag != dis {
            let m = ag.abs_diff(dis);
            adj[a as usize].push((b, m, dis > ag));
            adj[b as usize].push((a, m, dis > ag));
        }
    }
    // Groups, in order of their smallest patch.
    let mut group = vec![u32::MAX; np];
    let mut order: Vec<Vec<u32>> = Vec::new();
    for s in 0..np {
        if group[s] != u32::MAX {
            continue;
        }
        let g = order.len() as u32;
        group[s] = g;
        let mut list = vec![s as u32];
        let mut head = 0;
        while head < list.len() {
            let p = list[head] as usize;
            head += 1;
            for &(q, _, _) in &adj[p] {
                if group[q as usize] == u32::MAX {
                    group[q as usize] = g;
                    list.push(q);
                }
            }
        }
        order.push(list);
    }
    // The reference of each group: its best anchor, else its smallest patch.
    let mut reference: Vec<Option<PatchAnchor>> = vec![None; order.len()];
    for a in anchors.iter().filter(|a| (a.patch as usize) < np) {
        let r = &mut reference[group[a.patch as usize] as usize];
        let better = match r {
            None => true,
            Some(b) => a
                .dist2
                .total_cmp(&b.dist2)
                .then(b.id.cmp(&a.id))
                .then(b.patch.cmp(&a.patch))
                .is_gt(),
        };
        if better {
            *r = Some(*a);
        }
    }
    let mut flip = vec![false; np];
    let mut done = vec![false; np];
    // Max-heap on margin; ties to the smaller child, then the smaller parent.
    let mut heap: BinaryHeap<(u64, Reverse<u32>, Reverse<u32>, bool)> = BinaryHeap::new();
    for (g, list) in order.iter().enumerate() {
        let (root, root_flip) = match reference[g] {
            Some(a) => (a.patch as usize, !a.outward),
            None => (list[0] as usize, false),
        };
        flip[root] = root_flip;
        done[root] = true;
        let mut reached = root;
        loop {
            for &(q, m, opposite) in &adj[reached] {
                if !done[q as usize] {
                    heap.push((m, Reverse(q), Reverse(reached as u32), opposite));
                }
            }
            let next = loop {
                match heap.pop() {
                    Some((_, Reverse(q), _, _)) if done[q as usize] => continue,
                    other => break other,
                }
            };
            let Some((_, Reverse(q), Reverse(parent), opposite)) = next else {
                break;
            };
            let q = q as usize;
            done[q] = true;
            flip[q] = flip[parent as usize] != opposite;
            reached = q;
        }
    }
    let mut contradicted = 0;
    let mut total = 0;
    for (&(a, b), &(ag, dis)) in &margin {
        total += ag + dis;
        contradicted += if flip[a as usize] == flip[b as usize] {
            dis
        } else {
            ag
        };
    }
    PatchSigns {
        flip,
        contradicted,
        votes: total,
    }
}

/// A curvature result as it reads with the opposite normal: `H' = -H`, `K' = K`,
/// `k1' = -k2`, `k2' = -k1` (k1 stays the smaller), `d1' = d2`, `d2' = d1` (so that
/// `d1 x d2 = n` still holds). An estimator's own normal ([`Extra::normal`]) is negated with
/// the input normal it was oriented by; the feature score is unsigned. Flags are unchanged; NaN
/// stays NaN.
pub fn flip_curvature(c: &Curvature) -> Curvature {
    Curvature {
        h: -c.h,
        k: c.k,
        k1: -c.k2,
        k2: -c.k1,
        d1: c.d2,
        d2: c.d1,
        flags: c.flags,
        extra: c.extra.map(|e| Extra {
            normal: scale(e.normal, -1.0),
            ..e
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::{cross, norm, normalize};
    use crate::core::neighbors::{KnnScratch, NeighbourIndex};
    use crate::core::normals::pca_normal;
    use crate::core::rng::Rng;

    /// Fibonacci sphere of radius `r` around `c` with exact outward normals.
    fn sphere(n: usize, r: f64, c: V3) -> (Vec<V3>, Vec<V3>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let s = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let u = [s * t.cos(), s * t.sin(), z];
                (add(c, scale(u, r)), u)
            })
            .unzip()
    }

    /// A torus (R, r) in the xy plane with exact outward normals, on a jittered grid.
    fn torus(nu: usize, nv: usize, big: f64, small: f64) -> (Vec<V3>, Vec<V3>) {
        let mut rng = Rng::new(7);
        let tau = std::f64::consts::TAU;
        let mut p = Vec::new();
        let mut n = Vec::new();
        for a in 0..nu {
            for b in 0..nv {
                let u = (a as f64 + 0.3 * rng.uniform()) * tau / nu as f64;
                let v = (b as f64 + 0.3 * rng.uniform()) * tau / nv as f64;
                let dir = [v.cos() * u.cos(), v.cos() * u.sin(), v.sin()];
                let ring = [big * u.cos(), big * u.sin(), 0.0];
                p.push(add(ring, scale(dir, small)));
                n.push(dir);
            }
        }
        (p, n)
    }

    fn knn_lists(xyz: &[V3], k: usize) -> Vec<Vec<u32>> {
        let ids: Vec<u64> = (0..xyz.len() as u64).collect();
        let index = NeighbourIndex::build(xyz, &ids, k).expect("index");
        let mut s = KnnScratch::default();
        (0..xyz.len())
            .map(|i| {
                let mut out = Vec::new();
                index.knn(i, k, &mut s, &mut out);
                out
            })
            .collect()
    }

    /// PCA normals with random signs (PCA's own signs are arbitrary already; randomise anyway).
    fn scrambled_pca(xyz: &[V3], knn: &[Vec<u32>], seed: u64) -> Vec<Option<V3>> {
        let mut rng = Rng::new(seed);
        knn.iter()
            .map(|l| {
                pca_normal(xyz, l).map(|n| {
                    if rng.uniform() < 0.5 {
                        scale(n, -1.0)
                    } else {
                        n
                    }
                })
            })
            .collect()
    }

    fn wrong(normals: &[Option<V3>], truth: &[V3]) -> usize {
        normals
            .iter()
            .zip(truth)
            .filter(|(n, t)| n.is_some_and(|n| dot(n, **t) < 0.0))
            .count()
    }

    #[test]
    fn outward_is_exact_on_a_sphere_and_ties_are_deterministic() {
        let c = [500_000.0, 4_000_000.0, 100.0];
        let (p, n) = sphere(2000, 3.0, c);
        for (pi, ni) in p.iter().zip(&n) {
            assert_eq!(orient_outward(scale(*ni, -1.0), *pi, c), *ni);
            assert_eq!(orient_outward(*ni, *pi, c), *ni);
        }
        // Orthogonal: first non-zero component made positive, as normals::orient does.
        assert_eq!(
            orient_outward([0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0; 3]),
            [-0.0, 1.0, -0.0]
        );
        assert_eq!(
            orient_outward([0.0, -1.0, 0.0], [0.0; 3], [0.0; 3]),
            [-0.0, 1.0, -0.0]
        );
    }

    #[test]
    fn centroid_streams_and_merges() {
        let pts: Vec<V3> = (0..10)
            .map(|i| [600_000.0 + i as f64, 5_000_000.0 - i as f64, 0.5 * i as f64])
            .collect();
        let mut all = Centroid::default();
        pts.iter().for_each(|p| all.add(*p));
        let (mut a, mut b) = (Centroid::default(), Centroid::default());
        pts[..3].iter().for_each(|p| a.add(*p));
        pts[3..].iter().for_each(|p| b.add(*p));
        a.merge(&b);
        let want = [600_004.5, 4_999_995.5, 2.25];
        for c in [all.get().expect("points"), a.get().expect("points")] {
            assert!(norm(sub(c, want)) < 1e-9, "{c:?}");
        }
        assert_eq!(Centroid::default().get(), None);
    }

    #[test]
    fn propagation_orients_a_sphere_outward() {
        let (p, truth) = sphere(3000, 1.0, [10.0, -20.0, 5.0]);
        let knn = knn_lists(&p, 12);
        let mut normals = scrambled_pca(&p, &knn, 1);
        assert!(wrong(&normals, &truth) > 1000);
        let prop = propagate(&p, &knn, &normals, Seed::Outward);
        assert_eq!(prop.components.len(), 1);
        assert_eq!(prop.components[0].size, 3000);
        prop.apply(&mut normals);
        assert_eq!(wrong(&normals, &truth), 0);
    }

    #[test]
    fn propagation_orients_a_torus_and_each_of_two_objects() {
        let (mut p, mut truth) = torus(120, 40, 3.0, 1.0);
        // A second object, a sphere far away: its own component and seed.
        let (ps, ns) = sphere(800, 0.5, [20.0, 0.0, 0.0]);
        p.extend(ps);
        truth.extend(ns);
        let knn = knn_lists(&p, 10);
        let mut normals = scrambled_pca(&p, &knn, 2);
        let prop = propagate(&p, &knn, &normals, Seed::Outward);
        assert_eq!(prop.components.len(), 2);
        assert_eq!(prop.components[0].size, 4800);
        assert_eq!(prop.component[4800], 1);
        prop.apply(&mut normals);
        assert_eq!(wrong(&normals, &truth), 0);
        // Deterministic.
        assert_eq!(
            prop,
            propagate(&p, &knn, &scrambled_pca(&p, &knn, 2), Seed::Outward)
        );
    }

    #[test]
    fn propagation_skips_points_without_normals() {
        let (p, truth) = sphere(1000, 1.0, [0.0; 3]);
        let knn = knn_lists(&p, 10);
        let mut normals = scrambled_pca(&p, &knn, 3);
        for i in (0..1000).step_by(7) {
            normals[i] = None;
        }
        // Lists may be missing at the end (halo points without lists).
        let prop = propagate(&p, &knn[..900], &normals, Seed::OutwardFrom([0.0; 3]));
        assert_eq!(prop.component[7], Propagation::NONE);
        assert!(!prop.flip[7]);
        prop.apply(&mut normals);
        assert!(normals[7].is_none());
        assert_eq!(wrong(&normals, &truth), 0);
        // Nothing at all.
        let none = propagate(&p, &knn, &vec![None; 1000], Seed::Outward);
        assert!(none.components.is_empty());
    }

    /// The tiled scheme end to end on a sphere cut into 4 tiles (quadrants in x/y) with a halo:
    /// independent propagation per tile, tiles 1 and 2 then flipped wholesale (as a tile whose
    /// local seed lies might come out), votes from the overlap, one sign per tile.
    #[test]
    fn tiles_agree_through_their_halos() {
        let centre = [1.0, 2.0, 3.0];
        let (p, truth) = sphere(4000, 1.0, centre);
        let ids: Vec<u64> = (0..p.len() as u64).map(|i| i * 3 + 1).collect();
        let halo = 0.25;
        let mut shared = Vec::new();
        let mut anchors = Vec::new();
        // Per tile: (global index, oriented normal, patch) of its core points.
        let mut results: Vec<(usize, V3, u32)> = Vec::new();
        let mut next_patch = 0u32;
        for t in 0..4 {
            let pos = [t & 1 == 1, t & 2 == 2];
            // Inside the quadrant along axis a (0 belongs to the positive side), and distance
            // outside it.
            let inside = |q: &V3, a: usize| (q[a] - centre[a] >= 0.0) == pos[a];
            let out = |q: &V3, a: usize| {
                if inside(q, a) {
                    0.0
                } else {
                    (q[a] - centre[a]).abs()
                }
            };
            let in_core = |q: &V3| inside(q, 0) && inside(q, 1);
            let in_halo = |q: &V3| !in_core(q) && out(q, 0) <= halo && out(q, 1) <= halo;
            let mut local: Vec<usize> = (0..p.len()).filter(|&i| in_core(&p[i])).collect();
            let n_core = local.len();
            local.extend((0..p.len()).filter(|&i| in_halo(&p[i])));
            let lxyz: Vec<V3> = local.iter().map(|&i| p[i]).collect();
            let lids: Vec<u64> = local.iter().map(|&i| ids[i]).collect();
            let knn = knn_lists(&lxyz, 10);
            let mut normals = scrambled_pca(&lxyz, &knn, 10 + t as u64);
            let prop = propagate(&lxyz, &knn, &normals, Seed::OutwardFrom(centre));
            prop.apply(&mut normals);
            if t == 1 || t == 2 {
                normals
                    .iter_mut()
                    .flatten()
                    .for_each(|n| *n = scale(*n, -1.0));
            }
            let base = next_patch;
            next_patch += prop.components.len() as u32;
            for c in 0..prop.components.len() {
                let mut a = prop.anchor(c, base + c as u32, &lids);
                let s = prop.components[c].seed as usize;
                a.outward = normals[s].is_some_and(|n| dot(n, sub(lxyz[s], centre)) >= 0.0);
                anchors.push(a);
            }
            for (l, &g) in local.iter().enumerate() {
                let (Some(n), c) = (normals[l], prop.component[l]) else {
                    continue;
                };
                let near_edge =
                    (p[g][0] - centre[0]).abs() <= halo || (p[g][1] - centre[1]).abs() <= halo;
                if l >= n_core || near_edge {
                    shared.push(SharedNormal {
                        id: ids[g],
                        patch: base + c,
                        normal: n,
                    });
                }
                if l < n_core {
                    results.push((g, n, base + c));
                }
            }
        }
        // One component per tile here.
        assert_eq!(next_patch, 4);
        let votes = votes_from_shared(&mut shared);
        assert!(votes.len() >= 4, "{votes:?}");
        let signs = patch_signs(4, &votes, &anchors);
        assert_eq!(signs.contradicted, 0, "{votes:?}");
        assert_eq!(signs.flip, vec![false, true, true, false]);
        assert_eq!(results.len(), 4000);
        for &(g, n, patch) in &results {
            let n = if signs.flip[patch as usize] {
                scale(n, -1.0)
            } else {
                n
            };
            assert!(dot(n, truth[g]) > 0.0, "point {g}");
        }
    }

    #[test]
    fn patch_signs_follow_the_strongest_votes_and_the_farthest_anchor() {
        let v = |a, b, agree, disagree| PatchVote {
            a,
            b,
            agree,
            disagree,
        };
        // 0-1 agree, 1-2 disagree strongly, 0-2 weakly agree (contradiction: loses), 3 alone,
        // 4-5 tied (no information: separate groups).
        let votes = [v(0, 1, 50, 0), v(2, 1, 1, 40), v(0, 2, 3, 1), v(4, 5, 2, 2)];
        let anchor = |patch, dist2, outward| PatchAnchor {
            patch,
            dist2,
            id: patch as u64,
            outward,
        };
        // Patch 2's anchor is the farthest and says it is inward: 2 flips, 1 and 0 do not.
        let anchors = [
            anchor(0, 1.0, false),
            anchor(2, 4.0, false),
            anchor(3, 9.0, false),
            anchor(5, 1.0, true),
        ];
        let s = patch_signs(6, &votes, &anchors);
        assert_eq!(s.flip, vec![false, false, true, true, false, false]);
        assert_eq!(s.votes, 50 + 41 + 4 + 4);
        // 0-2: flips differ, so its 3 agreeing votes are contradicted; 1-2: its 1; 4-5: 2.
        assert_eq!(s.contradicted, 3 + 1 + 2);
        // Order of votes and anchors does not matter.
        let mut rv = votes.to_vec();
        rv.reverse();
        let mut ra = anchors.to_vec();
        ra.reverse();
        assert_eq!(patch_signs(6, &rv, &ra), s);
        // Out-of-range patches are ignored.
        assert_eq!(patch_signs(1, &votes, &anchors).flip, vec![true]);
    }

    #[test]
    fn flipping_curvature_twice_is_the_identity() {
        let n = [0.0, 0.0, 1.0];
        let c = Curvature {
            h: 1.5,
            k: 2.0,
            k1: 1.0,
            k2: 2.0,
            d1: [1.0, 0.0, 0.0],
            d2: [0.0, 1.0, 0.0],
            flags: 16,
            extra: Some(Extra {
                feature: 0.25,
                normal: n,
            }),
        };
        let f = flip_curvature(&c);
        assert_eq!((f.h, f.k, f.k1, f.k2), (-1.5, 2.0, -2.0, -1.0));
        assert!(f.k1 <= f.k2);
        assert_eq!(normalize(cross(f.d1, f.d2)), Some(scale(n, -1.0)));
        assert_eq!(
            f.extra.map(|e| (e.feature, e.normal)),
            Some((0.25, scale(n, -1.0)))
        );
        assert_eq!(flip_curvature(&f), c);
    }
}
