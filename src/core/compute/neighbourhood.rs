//! One point's estimator input: its neighbours' positions relative to it and their normals,
//! gathered from the tile's arrays into reusable buffers, and the flag for a curvature sharper
//! than the neighbourhood can hold.

use crate::core::estimate::{flags, Curvature, Estimator, Neighbourhood, Scratch};
use crate::core::geometry::{dot, sub, V3};
use crate::core::rng::position_key;

/// Reusable buffers for one point's estimator input and the estimator's own scratch (no
/// allocation per point).
pub struct NeighbourhoodBuf {
    pos: Vec<V3>,
    nrm: Vec<V3>,
    scratch: Scratch,
}

impl NeighbourhoodBuf {
    /// Buffers for neighbourhoods of up to `k` points.
    pub fn with_capacity(k: usize) -> Self {
        NeighbourhoodBuf {
            pos: Vec::with_capacity(k),
            nrm: Vec::with_capacity(k),
            scratch: Scratch::default(),
        }
    }

    /// Runs `estimator` on point `i` with its neighbour list `list` (local indices, `i` first):
    /// positions relative to point `i`, and only the neighbours that have a normal (the others
    /// cannot contribute to a measure); fewer than 3 such points give FEW_NEIGHBOURS. The
    /// random key is the point's [`position_key`], so that a randomised estimator's result
    /// depends on where the point is, not on its id. The estimator's first `extra.len()` extra
    /// values go to `extra`.
    pub fn estimate(
        &mut self,
        estimator: &dyn Estimator,
        xyz: &[V3],
        normals: &[Option<V3>],
        i: usize,
        list: &[u32],
        extra: &mut [f64],
    ) -> Curvature {
        // Grown to the list's length and written by index: pushing adds a capacity check and a
        // length update to every copy, which this short loop would mostly spend its time on.
        if self.pos.len() < list.len() {
            self.pos.resize(list.len(), [0.0; 3]);
            self.nrm.resize(list.len(), [0.0; 3]);
        }
        let mut m = 0;
        let q = xyz[i];
        // The squared radius of the neighbourhood, for the SHARPER_THAN_NEIGHBOURHOOD flag.
        let mut r2 = 0.0f64;
        for &j in list {
            if let Some(nj) = normals[j as usize] {
                let d = sub(xyz[j as usize], q);
                r2 = r2.max(dot(d, d));
                self.pos[m] = d;
                self.nrm[m] = nj;
                m += 1;
            }
        }
        if m < 3 {
            return Curvature::undefined(flags::FEW_NEIGHBOURS);
        }
        let mut c = estimator.estimate_extra(
            &Neighbourhood {
                positions: &self.pos[..m],
                normals: &self.nrm[..m],
                key: position_key(&q),
            },
            &mut self.scratch,
            extra,
        );
        if sharper_than(&c, r2.sqrt()) {
            c.flags |= flags::SHARPER_THAN_NEIGHBOURHOOD;
        }
        c
    }
}

/// Whether the curvature's largest magnitude times the neighbourhood radius `r` exceeds 2
/// (radius of curvature below r / 2: [`flags::SHARPER_THAN_NEIGHBOURHOOD`]). No sphere of
/// radius R holds points farther than 2R from one of its points, so such a value fits no
/// sphere through the neighbourhood. NaN parts (an estimator without k1, k2) are skipped.
pub(super) fn sharper_than(c: &Curvature, r: f64) -> bool {
    let kappa = [c.k1.abs(), c.k2.abs(), c.h.abs(), c.k.abs().sqrt()]
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    kappa * r > 2.0
}
