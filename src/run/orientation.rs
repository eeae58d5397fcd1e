//! `--orient propagate` across tiles: before the outputs are written, every tile's patch anchors
//! and shared normals are read back from the work directory and one sign per patch is solved
//! (core::orient::patch_signs), so that each output point's orientation agrees with its
//! neighbours' across tile borders.

use std::path::Path;

use crate::core::plan::TilePlan;
use crate::error::{Error, Result};
use crate::progress::Reporter;

/// `--orient propagate`, across tiles: reads every tile's patch anchors and shared normals,
/// turns the normals that two patches both oriented into votes, solves one sign per patch
/// (orient::patch_signs) and returns, per tile of the plan, which of its patches to flip.
pub(crate) fn resolve_orientation(
    dir: &Path,
    tplan: &TilePlan,
    reporter: &dyn Reporter,
) -> Result<Vec<Vec<bool>>> {
    let mut anchors = Vec::new();
    let mut shared = Vec::new();
    let mut offsets = Vec::with_capacity(tplan.tiles.len() + 1);
    offsets.push(0u32);
    for t in &tplan.tiles {
        let path = crate::io::workdir::results::orientation_path(dir, t.key);
        let sc = crate::io::workdir::results::read_sidecar(&path)?;
        let base = *offsets.last().unwrap_or(&0);
        // Patch numbers are u32 across the scene: a sum past that is damage, not data.
        let next = u32::try_from(sc.anchors.len())
            .ok()
            .and_then(|n| base.checked_add(n))
            .ok_or_else(|| Error::damaged_work(&path, "more than 2^32 patches in the scene"))?;
        anchors.extend(sc.anchors.iter().map(|a| crate::core::orient::PatchAnchor {
            patch: base + a.patch,
            ..*a
        }));
        shared.extend(sc.shared.iter().map(|s| crate::core::orient::SharedNormal {
            patch: base + s.patch,
            ..*s
        }));
        offsets.push(next);
    }
    let total = *offsets.last().unwrap_or(&0) as usize;
    let votes = crate::core::orient::votes_from_shared(&mut shared);
    let signs = crate::core::orient::patch_signs(total, &votes, &anchors);
    reporter.info(&format!(
        "orientation: {total} patches in {} tiles, {} shared normals voted, {} against the chosen signs, {} patches flipped",
        tplan.tiles.len(),
        signs.votes,
        signs.contradicted,
        signs.flip.iter().filter(|f| **f).count()
    ));
    Ok(offsets
        .windows(2)
        .map(|w| signs.flip[w[0] as usize..w[1] as usize].to_vec())
        .collect())
}
