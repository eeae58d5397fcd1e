//! Step 1 of the orientation (described in the parent module's documentation, which is what
//! "the module documentation" means below): [`propagate`], Hoppe's propagation over the symmetric
//! k-NN graph of one set of points, and [`orient_tile`], which runs it on a tile and numbers
//! its components as patches. Nothing here looks beyond one tile: the cross-tile sign solve is
//! `signs`. Pure: no I/O, no threads.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::ops::Range;

use super::signs::{PatchAnchor, SharedNormal};
use super::{orient_outward, Centroid};
use crate::core::geometry::{dot, scale, sub, V3};
use crate::core::point::cmp_position;

/// How [`propagate`] seeds each connected component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Seed {
    /// The component's point farthest from the component's own centroid, oriented away from it.
    /// For a whole object in memory.
    Outward,
    /// The component's point farthest from this centre, oriented away from it. For tiles: the
    /// centroid of the whole cloud, so that seeds of different tiles compare (see
    /// [`patch_signs`](super::patch_signs)).
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

    /// The anchor of component `c` as patch `patch`, for [`patch_signs`](super::patch_signs):
    /// `xyz` and `ids` are the points and their original ids (the slices the neighbour index
    /// was built with). The seed was oriented away from the centre, so `outward` is true.
    pub fn anchor(&self, c: usize, patch: u32, xyz: &[V3], ids: &[u64]) -> PatchAnchor {
        let comp = self.components[c];
        PatchAnchor {
            patch,
            dist2: comp.dist2,
            pos: xyz[comp.seed as usize],
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
    let labelled = label_components(knn, &rev, &live, &mut out);
    // 2. Seeds: farthest from the centre (ties: smaller position, then smaller index), oriented
    // away from it.
    for span in &labelled.spans {
        let members = &labelled.members[span.clone()];
        let comp = seed_component(xyz, normals, members, seed, &mut out.flip);
        out.components.push(comp);
    }
    drop(labelled);
    // 3. Prim's minimum spanning tree from each seed; each reached point agrees with its parent.
    grow_trees(knn, &rev, normals, &mut out);
    out
}

/// The members of the components [`label_components`] labels.
struct Members {
    /// The members of every component, component after component.
    members: Vec<u32>,
    /// Per component, where its members are in `members`.
    spans: Vec<Range<usize>>,
}

/// Step 1 of [`propagate`]: labels the components of the live points in `out.component`, by
/// breadth-first search from each unlabelled point in index order; their members in that order.
fn label_components<L: AsRef<[u32]>>(
    knn: &[L],
    rev: &InLists,
    live: &[bool],
    out: &mut Propagation,
) -> Members {
    let n = live.len();
    let mut queue: Vec<u32> = Vec::new();
    let mut members: Vec<u32> = Vec::new();
    let mut spans: Vec<Range<usize>> = Vec::new();
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
        spans.push(first..members.len());
    }
    Members { members, spans }
}

/// Step 2 of [`propagate`] for the component of points `pts`: its seed, the point farthest
/// from the centre `seed` names (among equally far points the smaller position by
/// [`cmp_position`], then the smaller index: the choice does not depend on the order of the
/// points, exact duplicates aside), whose normal is flipped in `flip` if it points inward.
fn seed_component(
    xyz: &[V3],
    normals: &[Option<V3>],
    pts: &[u32],
    seed: Seed,
    flip: &mut [bool],
) -> Component {
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
        let before = || {
            let (a, b) = (i as usize, best as usize);
            cmp_position(&xyz[a], &xyz[b]).then(i.cmp(&best)).is_lt()
        };
        if d2 > best_d || (d2 == best_d && before()) {
            (best, best_d) = (i, d2);
        }
    }
    let s = best as usize;
    if let Some(ns) = normals[s] {
        flip[s] = dot(orient_outward(ns, xyz[s], centre), ns) < 0.0;
    }
    Component {
        seed: best,
        dist2: best_d,
        size: pts.len() as u32,
    }
}

/// Step 3 of [`propagate`]: grows the minimum spanning tree of each component from its seed
/// (Prim's algorithm over the weights `1 - |<n_i, n_j>|`), setting `out.flip` of every point it
/// reaches so that it agrees with its tree parent.
fn grow_trees<L: AsRef<[u32]>>(
    knn: &[L],
    rev: &InLists,
    normals: &[Option<V3>],
    out: &mut Propagation,
) {
    let n = normals.len();
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
        .map(|c| prop.anchor(c, first_patch + c as u32, xyz, ids))
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
