use super::*;
use crate::io::columns::ColumnChoice;

fn cols() -> ColumnSet {
    cols_of("normals,H,K,k1,k2,flags")
}

fn cols_of(list: &str) -> ColumnSet {
    ColumnSet {
        choice: ColumnChoice::parse(list).expect("valid"),
        extra: Vec::new(),
        unit: "m".into(),
        wide: false,
    }
}

/// The record of point `i`: patch `patch` (or none), then columns from `i`.
fn record(i: u64, patch: Option<u64>, cols: &ColumnSet) -> Vec<u8> {
    let mut r = patch.unwrap_or(GlobalPatch::NONE.0).to_le_bytes().to_vec();
    r.extend((0..cols.result_size()).map(|j| (i.wrapping_mul(31) as usize + j * 7) as u8));
    r
}

/// Writes `ids` (with patches when `patched`) to `path`, renamed into place.
fn write(path: &Path, ids: &[u64], patched: bool) {
    write_cols(path, ids, patched, &cols())
}

/// [`write`] with the columns `cols`.
fn write_cols(path: &Path, ids: &[u64], patched: bool, cols: &ColumnSet) {
    let stats = CurvatureStats::default();
    let mut bufs = WriteBuffers::default();
    let mut w = ResultWriter::create(path, ids.len() as u64, cols, patched, &stats, &mut bufs)
        .expect("create");
    for &id in ids {
        w.push(id, &record(id, patched.then_some(id << 32 | 3), cols))
            .expect("push");
    }
    let tmp = w.finish().expect("finish");
    std::fs::rename(tmp, path).expect("rename");
}

fn read_all(path: &Path) -> Result<Vec<(u64, Vec<u8>)>> {
    read_cols(path, &cols())
}

/// [`read_all`] with the columns `cols`.
fn read_cols(path: &Path, cols: &ColumnSet) -> Result<Vec<(u64, Vec<u8>)>> {
    let mut r = TileResults::open(path, cols)?;
    let mut out = Vec::new();
    let mut rec = Vec::new();
    while let Some(id) = r.next(&mut rec)? {
        out.push((id, rec.clone()));
    }
    Ok(out)
}

#[test]
fn result_files_round_trip_over_many_blocks() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cols = cols();
    // Runs of consecutive ids with jumps, over several blocks (32 KiB is ~1100 records here).
    let ids: Vec<u64> = (0..10_000u64)
        .map(|i| i + (i / 1000) * 50_000 + 5)
        .collect();
    for patched in [false, true] {
        let path = dir.path().join(format!("tile_{patched}.res"));
        write(&path, &ids, patched);
        let back = read_all(&path).expect("read");
        assert_eq!(back.len(), ids.len());
        for ((id, rec), &want) in back.iter().zip(&ids) {
            assert_eq!(*id, want);
            assert_eq!(*rec, record(want, patched.then_some(want << 32 | 3), &cols));
        }
        assert!(TileResults::open(&path, &cols)
            .expect("open")
            .verify()
            .is_ok());
        assert_eq!(
            TileResults::open(&path, &cols).expect("open").patched(),
            patched
        );
        // The records repeat every 256 ids and the ids run in steps of one: the planes in the
        // frame (the patch if any, the top bytes, H, the flags, a varint gap) compressed to
        // well under a quarter, the plain ones (three bytes of each number but H) as they are.
        let plain = RowSplit::of(&cols, patched, true).plain_count();
        assert_eq!(plain, 6 * 3);
        let packed = cols.result_size() + if patched { 8 } else { 0 } + 1 - plain;
        let size = std::fs::metadata(&path).expect("size").len();
        let (at_least, under) = (ids.len() * plain, ids.len() * (plain + packed / 4));
        assert!(
            (at_least as u64..under as u64).contains(&size),
            "{size} bytes: {at_least} plain, {} in the frame before compression",
            ids.len() * packed
        );
    }
    // Empty results are a valid file.
    let empty = dir.path().join("empty.res");
    write(&empty, &[], false);
    assert!(read_all(&empty).expect("read").is_empty());
}

/// The terrain numbers, kept as they are at the start of each block's plain bytes: records go
/// through a file unchanged with and without patches over several blocks, the file holds at
/// least their bytes (they are not compressed), and a byte flipped among them is refused.
#[test]
fn terrain_numbers_are_kept_as_they_are_and_checked() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cols = cols_of("H,K,flags,terrain");
    let ids: Vec<u64> = (0..5000u64).map(|i| 3 * i + 1).collect();
    for patched in [false, true] {
        let path = dir.path().join(format!("terrain_{patched}.res"));
        write_cols(&path, &ids, patched, &cols);
        let back = read_cols(&path, &cols).expect("read");
        assert_eq!(back.len(), ids.len());
        for ((id, rec), &want) in back.iter().zip(&ids) {
            assert_eq!(*id, want);
            assert_eq!(*rec, record(want, patched.then_some(want << 32 | 3), &cols));
        }
        let size = std::fs::metadata(&path).expect("size").len() as usize;
        // Seven f32 numbers and the low bytes of H and K (not predicted without k1 and k2),
        // whatever the frame compresses to.
        assert!(size >= ids.len() * (7 * 4 + 2 * 3), "{size} bytes");
        assert!(super::super::is_complete(&path, ids.len() as u64, &cols));
        // The first block's raw bytes start its plain bytes, right after its lengths: the
        // first record's seven numbers are there as the record holds them.
        let good = std::fs::read(&path).expect("read");
        let stats = u64::from_le_bytes(good[32..40].try_into().expect("8 bytes")) as usize;
        let block = HEAD + stats;
        let word = |at: usize| u32::from_le_bytes(good[at..at + 4].try_into().expect("4")) as usize;
        let (n, plain) = (word(block), word(block + 12));
        assert_eq!(plain, n * (2 * 3 + 7 * 4));
        let first = record(ids[0], patched.then_some(ids[0] << 32 | 3), &cols);
        let raw_at = block + BLOCK_HEAD;
        assert_eq!(good[raw_at..raw_at + 28], first[first.len() - 28..]);
        for at in [raw_at, raw_at + n * 28 - 1] {
            let mut bad = good.clone();
            bad[at] ^= 0x01;
            std::fs::write(&path, &bad).expect("write");
            assert!(!super::super::is_complete(&path, ids.len() as u64, &cols));
            let e = read_cols(&path, &cols).expect_err("a raw byte damaged");
            assert!(e.to_string().contains("damaged block"), "{e}");
        }
    }
}

#[test]
fn writer_refuses_unordered_ids_and_stray_patches() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (cols, stats) = (cols(), CurvatureStats::default());
    let path = dir.path().join("t.res");
    let mut bufs = WriteBuffers::default();
    let mut w = ResultWriter::create(&path, 3, &cols, false, &stats, &mut bufs).expect("create");
    w.push(4, &record(4, None, &cols)).expect("first");
    assert!(w.push(4, &record(4, None, &cols)).is_err());
    assert!(w.push(9, &record(9, Some(1), &cols)).is_err());
    let mut w = ResultWriter::create(&path, 3, &cols, false, &stats, &mut bufs).expect("create");
    w.push(1, &record(1, None, &cols)).expect("push");
    assert!(w.finish().is_err(), "fewer records than declared");
}

#[test]
fn damaged_truncated_and_old_result_files_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cols = cols();
    let path = dir.path().join("tile_0_0.res");
    let ids: Vec<u64> = (0..5000).collect();
    write(&path, &ids, false);
    let good = std::fs::read(&path).expect("read");
    let check = |bytes: &[u8], what: &str| {
        std::fs::write(&path, bytes).expect("write");
        assert!(
            !super::super::is_complete(&path, 5000, &cols),
            "{what}: taken as complete"
        );
        let e = read_all(&path)
            .map(|_| ())
            .and_then(|_| TileResults::open(&path, &cols)?.verify())
            .expect_err(what);
        assert_eq!(e.exit_class(), crate::error::ExitClass::Output, "{what}");
        let msg = e.to_string();
        assert!(
            msg.contains("tile_0_0.res") && msg.contains("delete the work directory"),
            "{what}: {msg}"
        );
    };
    std::fs::write(&path, &good).expect("write");
    assert!(super::super::is_complete(&path, 5000, &cols));
    assert!(!super::super::is_complete(&path, 4999, &cols));
    check(&good[..good.len() - 1], "truncated by a byte");
    check(&good[..good.len() / 2], "truncated by half");
    let mut longer = good.clone();
    longer.push(0);
    check(&longer, "a byte too many");
    for at in [HEAD + 200, good.len() / 2, good.len() - 5] {
        let mut bad = good.clone();
        bad[at] ^= 0x04;
        check(&bad, &format!("a bit flipped at {at}"));
    }
    // The first block's plain planes after its lengths, then its frame and the plain planes'
    // checksum.
    let stats = u64::from_le_bytes(good[32..40].try_into().expect("8 bytes")) as usize;
    let block = HEAD + stats;
    let frame = u32::from_le_bytes(good[block + 8..block + 12].try_into().expect("4 bytes"));
    let plain = u32::from_le_bytes(good[block + 12..block + 16].try_into().expect("4 bytes"));
    let (plain, frame) = (plain as usize, frame as usize);
    let plain_at = block + BLOCK_HEAD;
    assert_eq!(plain, 18 * (BLOCK_BYTES / cols.result_size()));
    for (at, what) in [
        (plain_at, "the first plain byte"),
        (plain_at + plain / 2, "a plain byte"),
        (plain_at + plain + frame / 2, "a frame byte"),
        (plain_at + plain + frame + 3, "the plain planes' checksum"),
        (block + 12, "the plain length"),
        (
            plain_at + plain + frame + 8 + 8,
            "the second block's frame length",
        ),
    ] {
        let mut bad = good.clone();
        bad[at] ^= 0x10;
        check(&bad, &format!("{what} damaged"));
    }
    let mut old = good.clone();
    old[..8].copy_from_slice(b"TCRES009");
    check(&old, "the previous format");
}

#[test]
fn the_h_prediction_is_exact_and_pays() {
    use crate::core::compute::{PointResult, NO_PATCH};
    use crate::core::estimate::{Curvature, MAX_EXTRA};
    let dir = tempfile::tempdir().expect("temp dir");
    for wide in [false, true] {
        let cols = ColumnSet { wide, ..cols() };
        let p = HPrediction::of(&cols).expect("H, k1 and k2 are stored");
        // k1, k2 noisy; H their mean (as most estimators give it) or not; NaN and infinities.
        let special = [f64::NAN, f64::INFINITY, -f64::INFINITY, 0.0, -0.0];
        let results: Vec<PointResult> = (0..6000u64)
            .map(|i| {
                let k1 = ((i * 2_654_435_761) % 1_000_003) as f64 * 1e-9 - 5e-4;
                let k2 = k1 + ((i * 40_503) % 65_537) as f64 * 1e-9;
                let h = match i % 4 {
                    0 => (k1 + k2) / 2.0,
                    1 => (k1 + k2) / 2.0 * (1.0 + 1e-7),
                    _ => (k1 as f32 as f64 + k2 as f32 as f64) / 2.0,
                };
                let (k1, h) = if i % 97 == 0 {
                    (
                        special[(i / 97) as usize % 5],
                        special[(i / 3) as usize % 5],
                    )
                } else {
                    (k1, h)
                };
                PointResult {
                    id: i,
                    normal: [0.0, 0.6, 0.8],
                    curvature: Curvature {
                        h,
                        k: k1 * k2,
                        k1,
                        k2,
                        ..Curvature::undefined(0)
                    },
                    extra: [f64::NAN; MAX_EXTRA],
                    patch: NO_PATCH,
                    scale: 0,
                    scale_flags: 0,
                    terrain: crate::core::terrain::TerrainValues::NONE,
                }
            })
            .collect();
        let encoded: Vec<Vec<u8>> = results
            .iter()
            .map(|r| {
                let mut b = GlobalPatch::NONE.0.to_le_bytes().to_vec();
                cols.layout().encode(r, &mut b);
                b
            })
            .collect();
        // Applied twice, the identity; applied once, H's bits mostly cleared.
        let mut cleared = 0;
        for e in &encoded {
            let mut c = e[8..].to_vec();
            p.apply(&mut c);
            let h = cols.stored_offset(Value::H).expect("H");
            cleared += c[h..h + if wide { 8 } else { 4 }].iter().all(|&b| b == 0) as usize;
            p.apply(&mut c);
            assert_eq!(c, e[8..]);
        }
        assert!(
            cleared > encoded.len() / 5,
            "{cleared} of {} predicted exactly",
            encoded.len()
        );
        let path = dir.path().join(format!("h_{wide}.res"));
        let stats = CurvatureStats::default();
        let mut bufs = WriteBuffers::default();
        let mut w =
            ResultWriter::create(&path, encoded.len() as u64, &cols, false, &stats, &mut bufs)
                .expect("create");
        for (i, e) in encoded.iter().enumerate() {
            w.push(i as u64, e).expect("push");
        }
        std::fs::rename(w.finish().expect("finish"), &path).expect("rename");
        let mut r = TileResults::open(&path, &cols).expect("open");
        let mut rec = Vec::new();
        for e in &encoded {
            r.next(&mut rec).expect("next").expect("a record");
            assert_eq!(rec, *e);
        }
        assert!(r.next(&mut rec).expect("end").is_none());
    }
}

/// Buffers kept from one file to the next write the bytes fresh ones write: after a larger
/// file with patches, and after a writer that stopped with an error halfway through a block.
#[test]
fn kept_buffers_write_what_fresh_ones_write() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (cols, stats) = (cols(), CurvatureStats::default());
    let file = |name: &str, ids: &[u64], patched: bool, bufs: &mut WriteBuffers| {
        let path = dir.path().join(name);
        let mut w = ResultWriter::create(&path, ids.len() as u64, &cols, patched, &stats, bufs)
            .expect("create");
        for &id in ids {
            w.push(id, &record(id, patched.then_some(id << 32 | 3), &cols))
                .expect("push");
        }
        std::fs::read(w.finish().expect("finish")).expect("read")
    };
    let small: Vec<u64> = (0..700).map(|i| 3 * i + 1).collect();
    let large: Vec<u64> = (0..5000).collect();
    let fresh = file("fresh.res", &small, false, &mut WriteBuffers::default());
    let mut kept = WriteBuffers::default();
    file("large.res", &large, true, &mut kept);
    let path = dir.path().join("failed.res");
    let mut w = ResultWriter::create(&path, 10, &cols, false, &stats, &mut kept).expect("create");
    w.push(8, &record(8, None, &cols)).expect("push");
    assert!(w.push(2, &record(2, None, &cols)).is_err(), "out of order");
    assert_eq!(file("kept.res", &small, false, &mut kept), fresh);
}
