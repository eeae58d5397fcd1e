//! The one harness of every target: open the bytes as a file of one format through the same
//! code a run uses (`open_bytes`, in memory: no file per iteration), then everything a run asks
//! of a source: its properties, unit and every record decoded and checked as the scan does.
//! Errors are the expected outcome of most inputs; a panic, an abort or a hang is a finding.

use std::path::Path;

use tilecurv::core::plan::{computable, TileGrid};
use tilecurv::io::source::{open_bytes, Format, InputBytes};

/// Runs the harness on `data` as a `format` file.
pub fn run(format: Format, data: &[u8]) {
    let Ok(s) = open_bytes(
        Path::new("fuzz-input"),
        format,
        InputBytes::Owned(data.to_vec()),
    ) else {
        return;
    };
    let _ = (
        s.len(),
        s.properties(),
        s.unit(),
        s.describe(),
        s.has_normals(),
    );
    let rl = s.record_length().max(1);
    let grid = TileGrid { size: 50.0 };
    let _ = s.for_each_chunk(4096, &mut |first, records| {
        for (i, rec) in records.chunks_exact(rl).enumerate() {
            let p = s.decode(first + i as u64, rec);
            if computable(p.xyz) && grid.holds(p.xyz[0], p.xyz[1]) {
                std::hint::black_box(grid.key(p.xyz[0], p.xyz[1]));
            }
        }
        Ok(())
    });
}
