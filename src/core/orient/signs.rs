//! Step 2 of the orientation (see the parent module's documentation): what tiles report to the
//! cross-tile step ([`PatchAnchor`], [`SharedNormal`]), the agreement votes between patches
//! ([`votes_from_shared`]) and the solve of one sign per patch ([`patch_signs`]). It sees only
//! the patch tables, never a tile's points. Pure: no I/O, no threads.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};

use crate::core::geometry::{dot, V3};
use crate::core::point::cmp_point;

/// Where a patch's orientation is known from its seed: a candidate for the reference of its
/// connected group of patches in [`patch_signs`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchAnchor {
    /// The patch.
    pub patch: u32,
    /// Squared distance of the anchor point from the common centre (the global centroid).
    pub dist2: f64,
    /// Position of the anchor point (breaks ties between anchors at the same distance).
    pub pos: V3,
    /// Original id of the anchor point (breaks ties between exact duplicates).
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
/// largest `dist2` (ties: the smaller position, then id, by [`cmp_point`], then the smaller
/// patch) fixes its patch's sign (flip it unless `outward`); the other patches follow a maximum
/// spanning tree of the margins `|agree - disagree|` from there (ties: smaller patch index),
/// each taking its tree parent's sign when its votes mostly agree and the opposite otherwise. A
/// group without an anchor keeps its reference patch (the smallest index) as it is. Votes and
/// anchors naming patches out of range are ignored. Deterministic, and independent of the order
/// of `votes` and `anchors`.
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
    let mut adj: Vec<Vec<Link>> = vec![Vec::new(); np];
    for (&(a, b), &(ag, dis)) in &margin {
        if ag != dis {
            let (margin, opposite) = (ag.abs_diff(dis), dis > ag);
            adj[a as usize].push(Link {
                to: b,
                margin,
                opposite,
            });
            adj[b as usize].push(Link {
                to: a,
                margin,
                opposite,
            });
        }
    }
    // Groups, in order of their smallest patch.
    let Groups { of: group, order } = patch_groups(&adj);
    // The reference of each group: its best anchor, else its smallest patch.
    let mut reference: Vec<Option<PatchAnchor>> = vec![None; order.len()];
    for a in anchors.iter().filter(|a| (a.patch as usize) < np) {
        let r = &mut reference[group[a.patch as usize] as usize];
        let better = match r {
            None => true,
            Some(b) => a
                .dist2
                .total_cmp(&b.dist2)
                .then_with(|| cmp_point((&b.pos, b.id), (&a.pos, a.id)))
                .then(b.patch.cmp(&a.patch))
                .is_gt(),
        };
        if better {
            *r = Some(*a);
        }
    }
    let flip = follow_margins(&order, &reference, &adj);
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

/// A link of the patch graph: a neighbouring patch and the margin of their votes.
#[derive(Debug, Clone, Copy)]
struct Link {
    /// The neighbouring patch.
    to: u32,
    /// |agree - disagree| of their votes (never 0: tied pairs are not linked).
    margin: u64,
    /// Whether their votes mostly disagree: the two take opposite signs.
    opposite: bool,
}

/// The connected groups of patches ([`patch_groups`]).
struct Groups {
    /// Per patch, its group.
    of: Vec<u32>,
    /// Per group, its patches in breadth-first order from the smallest.
    order: Vec<Vec<u32>>,
}

/// The connected groups of patches in the graph `adj` (index order of their smallest patch).
fn patch_groups(adj: &[Vec<Link>]) -> Groups {
    let np = adj.len();
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
            for &Link { to: q, .. } in &adj[p] {
                if group[q as usize] == u32::MAX {
                    group[q as usize] = g;
                    list.push(q);
                }
            }
        }
        order.push(list);
    }
    Groups { of: group, order }
}

/// The flip of every patch: in each group of `order`, its reference (`reference`: the anchor's
/// sign, else its first patch unflipped) and then a maximum spanning tree of the margins in
/// `adj`, each patch taking its tree parent's sign unless their votes mostly disagree.
fn follow_margins(
    order: &[Vec<u32>],
    reference: &[Option<PatchAnchor>],
    adj: &[Vec<Link>],
) -> Vec<bool> {
    let np = adj.len();
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
            for l in &adj[reached] {
                if !done[l.to as usize] {
                    heap.push((l.margin, Reverse(l.to), Reverse(reached as u32), l.opposite));
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
    flip
}
