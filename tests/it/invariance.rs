//! Tiling is invisible: every output column is bit-identical whatever the tile size, the thread
//! count, the read chunk size or the memory budget (spilled buckets, quadtree parts), on real
//! files (LAS and LAZ input).

use crate::common::{column_bytes, process, shared, COLUMNS};

fn assert_same_columns(a: &std::path::Path, b: &std::path::Path) {
    for name in COLUMNS {
        assert!(
            column_bytes(a, name) == column_bytes(b, name),
            "column {name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn tiles_threads_and_chunks_do_not_change_results() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (file, tiles) in [
        ("las/Topography.las", ["5m", "20m", "100000m"]),
        ("las/autzen_trim.laz", ["5m", "20m", "100000m"]),
    ] {
        let Some(input) = shared(file) else { continue };
        let reference = dir.path().join("ref.las");
        process(&input, &reference, &["--tile", tiles[2], "--threads", "1"]);
        for tile in tiles {
            for threads in ["1", "2"] {
                for chunk in ["1000000", "4099"] {
                    if (tile, threads, chunk) == (tiles[2], "1", "1000000") {
                        continue;
                    }
                    let out = dir.path().join(format!("t{tile}_{threads}_{chunk}.las"));
                    process(
                        &input,
                        &out,
                        &["--tile", tile, "--threads", threads, "--chunk-size", chunk],
                    );
                    assert_same_columns(&reference, &out);
                    std::fs::remove_file(&out).expect("cleanup");
                }
            }
        }
        // A small memory budget: buckets spill to disk and the one big tile is computed in
        // quadtree parts.
        let out = dir.path().join("parts.las");
        process(&input, &out, &["--tile", tiles[2], "--memory", "64M"]);
        assert_same_columns(&reference, &out);
    }
}
