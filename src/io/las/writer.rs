//! The one LAS/LAZ writer, used by `process` (through `io::sink`) and by `generate terrain`:
//! [`LasFileWriter`] writes a header (an input's, carried over, or a new one), VLRs, point
//! records (LAS or LAZ, chosen by the output's extension; LAZ through the laz crate's parallel
//! compressor in fixed chunks) and EVLRs to a temporary file beside the output, patches the
//! header's layout fields (and, if asked, its bounds) at the end, syncs the file and renames it
//! over the output on `finish` (after checking that as many records were written as the header
//! counts); any failure, `abandon` or a drop removes it (`TempFile`). It knows the LAS format, not where the records come from:
//! `carry` and `convert` build its [`LasFileSpec`] for `process`.

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::os::unix::fs::FileExt;
use std::path::Path;

use crate::error::{Error, Result};
use crate::io::direct::DirectFile;
use crate::io::durable::{Ready, TempFile};
use crate::io::las::extra_bytes;
use crate::io::las::header::{LasHeader, NewHeader, OutputLayout, POINT_FORMAT_SIZES};
use crate::io::las::provenance::PROVENANCE;
use crate::io::las::vlr::{laszip, Vlr};
use crate::io::output::PointSink;

/// Whether a path names a LAZ file (by extension; anything else that is .las is LAS).
fn output_is_laz(path: &Path) -> Result<bool> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("laz") => Ok(true),
        Some("las") => Ok(false),
        _ => Err(Error::Usage(format!(
            "{}: the output must end in .las or .laz (the extension chooses the format)",
            path.display()
        ))),
    }
}

/// The header a file starts from.
#[derive(Debug, Clone)]
pub enum HeaderStart<'a> {
    /// An input's header: every field but the layout ones (GUID, system identifier, dates,
    /// counts, bounds) is written back untouched.
    Input(&'a LasHeader),
    /// A header written from scratch (a generated or converted cloud).
    New(NewHeader<'a>),
}

/// Everything of a LAS/LAZ file but its point records.
#[derive(Debug, Clone)]
pub struct LasFileSpec<'a> {
    /// The input the header and VLRs come from, named in errors about them; `None` for a
    /// generated file (such an error is then internal).
    pub origin: Option<&'a Path>,
    /// The header to start from.
    pub header: HeaderStart<'a>,
    /// Bytes per output record (the header's record length plus any new columns).
    pub record_length: u16,
    /// The VLRs to carry over, in order; LASzip records (rebuilt when the output is LAZ) and
    /// COPC records (whose index would be stale) are dropped.
    pub vlrs: &'a [Vlr],
    /// The EVLRs to carry over with their byte offsets in the input (the header's waveform
    /// start names the waveform record, which is then located in the output); COPC dropped.
    pub evlrs: &'a [(u64, Vlr)],
    /// The extra-bytes descriptors of the output records (encoded), written as exactly one
    /// record: in place of the first carried extra-bytes VLR (else EVLR), the others dropped
    /// (their descriptors are expected in this payload), or as a new VLR after the carried
    /// ones if there is none; as an EVLR (the first carried one, else a new one after the
    /// others) when they do not fit a VLR (more than 65535 bytes: 341 descriptors), which
    /// only a LAS 1.4 file has.
    pub extra_bytes: Vec<u8>,
    /// The provenance text, written as the provenance VLR (after the extra bytes).
    pub provenance: &'a str,
}

impl LasFileSpec<'_> {
    /// A bad-input error about the origin, or an internal one for a generated file.
    fn error(&self, what: String) -> Error {
        match self.origin {
            Some(path) => Error::bad_input(path, None, what),
            None => Error::Internal(what),
        }
    }

    /// The header to patch: the input's, or a new one parsed back (so both follow one path).
    fn start_header(&self, output: &Path) -> Result<LasHeader> {
        match &self.header {
            HeaderStart::Input(h) => Ok((*h).clone()),
            HeaderStart::New(h) => {
                let raw = h.bytes();
                LasHeader::parse(self.origin.unwrap_or(output), &raw, raw.len() as u64).map_err(
                    |e| match self.origin {
                        Some(_) => e,
                        None => Error::Internal(format!("a new LAS header: {e}")),
                    },
                )
            }
        }
    }

    /// The output's VLRs: the carried ones with the extra-bytes payload in place (or a new
    /// extra-bytes VLR after them), the provenance, and the LASzip VLR for a LAZ output.
    fn vlrs(&self, header: &LasHeader, compressed: bool) -> Result<Vlrs> {
        let mut vlrs: Vec<Vlr> = Vec::new();
        let home = self.extra_bytes_home();
        for v in self.vlrs {
            if is_laszip(v) || is_copc(v) {
                continue;
            }
            if extra_bytes::is_extra_bytes(v) {
                if home == ExtraBytesHome::FirstVlr && !vlrs.iter().any(extra_bytes::is_extra_bytes)
                {
                    vlrs.push(self.with_extra_bytes(v));
                }
            } else {
                vlrs.push(v.clone());
            }
        }
        if home == ExtraBytesHome::NewVlr {
            vlrs.push(extra_bytes::vlr(self.extra_bytes.clone()));
        }
        vlrs.push(Vlr::new(
            PROVENANCE.0,
            PROVENANCE.1,
            "tilecurv provenance",
            self.provenance.as_bytes().to_vec(),
        ));
        if !compressed {
            return Ok(Vlrs { vlrs, laz: None });
        }
        let extra = self.record_length - POINT_FORMAT_SIZES[header.point_format as usize];
        let laz = laszip(header.point_format, extra)?;
        vlrs.push(laz.vlr);
        Ok(Vlrs {
            vlrs,
            laz: Some(laz.layout),
        })
    }

    /// The output's EVLRs (COPC dropped, the extra bytes in the first extra-bytes EVLR if no
    /// VLR holds them, other extra-bytes EVLRs dropped) and the index of the waveform record
    /// among them.
    fn evlrs(&self, header: &LasHeader) -> Evlrs {
        let mut evlrs: Vec<Vlr> = Vec::new();
        let mut waveform = None;
        let home = self.extra_bytes_home();
        for (off, v) in self.evlrs {
            if is_copc(v) {
                continue;
            }
            if *off == header.waveform_start {
                waveform = Some(evlrs.len());
            }
            if extra_bytes::is_extra_bytes(v) {
                if home == ExtraBytesHome::FirstEvlr
                    && !evlrs.iter().any(extra_bytes::is_extra_bytes)
                {
                    evlrs.push(self.with_extra_bytes(v));
                }
            } else {
                evlrs.push(v.clone());
            }
        }
        if home == ExtraBytesHome::NewEvlr {
            evlrs.push(extra_bytes::vlr(self.extra_bytes.clone()));
        }
        Evlrs { evlrs, waveform }
    }

    /// Where the one extra-bytes record of the output goes.
    fn extra_bytes_home(&self) -> ExtraBytesHome {
        let fits = self.extra_bytes.len() <= u16::MAX as usize;
        let in_vlr = self.vlrs.iter().any(extra_bytes::is_extra_bytes);
        let in_evlr = self
            .evlrs
            .iter()
            .any(|(_, v)| extra_bytes::is_extra_bytes(v));
        match (in_vlr && fits, in_evlr, fits) {
            (true, _, _) => ExtraBytesHome::FirstVlr,
            (false, true, _) => ExtraBytesHome::FirstEvlr,
            (false, false, true) => ExtraBytesHome::NewVlr,
            (false, false, false) => ExtraBytesHome::NewEvlr,
        }
    }

    fn with_extra_bytes(&self, v: &Vlr) -> Vlr {
        Vlr {
            data: self.extra_bytes.clone(),
            ..v.clone()
        }
    }
}

/// An output's VLRs ([`LasFileSpec::vlrs`]).
struct Vlrs {
    /// The records, in order.
    vlrs: Vec<Vlr>,
    /// The LASzip layout they describe, for a LAZ output.
    laz: Option<laz::LazVlr>,
}

/// An output's EVLRs ([`LasFileSpec::evlrs`]).
struct Evlrs {
    /// The records, in order.
    evlrs: Vec<Vlr>,
    /// The index of the waveform record among them.
    waveform: Option<usize>,
}

/// Where the output's one extra-bytes record is written: in place of the input's first
/// extra-bytes VLR (if the descriptors fit a VLR), else of its first extra-bytes EVLR, else
/// as a new VLR, or a new EVLR if they do not fit one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ExtraBytesHome {
    FirstVlr,
    FirstEvlr,
    NewVlr,
    NewEvlr,
}

/// Why extra-bytes descriptors of `bytes` bytes cannot be written in a LAS file of `version`
/// (before 1.4: no EVLR), and what to do.
pub fn too_many_descriptors(bytes: usize, version: (u8, u8)) -> String {
    format!(
        "the output needs {} extra-bytes descriptors ({bytes} bytes), more than a VLR holds (65535 bytes, 341 descriptors), and a LAS {}.{} file has no EVLRs to hold them; write LAS 1.4 (without --keep-version) or fewer columns (--columns)",
        bytes / extra_bytes::DESCRIPTOR_SIZE,
        version.0,
        version.1
    )
}

fn is_laszip(v: &Vlr) -> bool {
    v.is("laszip encoded", 22204)
}

fn is_copc(v: &Vlr) -> bool {
    v.user_id == "copc"
}

/// Where the point records go.
enum Points {
    Plain(DirectFile),
    Laz(Box<laz::ParLasZipCompressor<BufWriter<File>>>),
}

/// A LAS/LAZ file being written (see the module doc).
pub struct LasFileWriter {
    /// Removed on every path but a successful `finish`.
    tmp: TempFile,
    /// The header, patched with `layout` when written.
    header: LasHeader,
    layout: OutputLayout,
    evlrs: Vec<Vlr>,
    /// Index of the waveform record in `evlrs`.
    waveform_evlr: Option<usize>,
    points: Points,
    /// Point records written so far, checked against the header's count on `finish`.
    written: u64,
}

impl LasFileWriter {
    /// Creates the temporary file beside `output` and writes the header and VLRs; LAZ when
    /// `output` ends in `.laz`.
    pub fn create(output: &Path, spec: LasFileSpec<'_>) -> Result<Self> {
        let compressed = output_is_laz(output)?;
        let header = spec.start_header(output)?;
        let Vlrs { vlrs, laz: laz_vlr } = spec.vlrs(&header, compressed)?;
        let Evlrs {
            evlrs,
            waveform: waveform_evlr,
        } = spec.evlrs(&header);
        if spec.extra_bytes.len() > u16::MAX as usize && header.version.1 < 4 {
            return Err(spec.error(too_many_descriptors(spec.extra_bytes.len(), header.version)));
        }
        let mut head = Vec::new();
        for v in &vlrs {
            v.write_vlr(&mut head).map_err(|why| spec.error(why))?;
        }
        let offset = header.header_size as usize + head.len();
        let layout = OutputLayout {
            offset_to_point_data: u32::try_from(offset)
                .map_err(|_| Error::Internal("VLRs larger than 4 GiB".into()))?,
            num_vlrs: vlrs.len() as u32,
            compressed,
            record_length: spec.record_length,
            evlr_start: 0,
            evlr_count: evlrs.len() as u32,
            waveform_start: 0,
        };
        let (tmp, file) = TempFile::create(output)?;
        let start = [header.patched(&layout), head].concat();
        let points = match laz_vlr {
            None => {
                let mut w = DirectFile::new(file, tmp.path());
                w.write_all(&start).map_err(|e| tmp.error(e))?;
                Points::Plain(w)
            }
            Some(lv) => {
                let mut w = BufWriter::with_capacity(4 << 20, file);
                w.write_all(&start).map_err(|e| tmp.error(e))?;
                Points::Laz(Box::new(
                    laz::ParLasZipCompressor::new(w, lv).map_err(|e| laz_error(&tmp, e))?,
                ))
            }
        };
        Ok(LasFileWriter {
            tmp,
            header,
            layout,
            evlrs,
            waveform_evlr,
            points,
            written: 0,
        })
    }

    /// Appends whole point records of the output's record length, in file order.
    pub fn write_records(&mut self, records: &[u8]) -> Result<()> {
        let r = match &mut self.points {
            Points::Plain(w) => w.write_all(records),
            Points::Laz(c) => c.compress_many(records).map_err(laz_io),
        };
        r.map_err(|e| self.tmp.error(e))?;
        self.written += (records.len() / self.layout.record_length as usize) as u64;
        Ok(())
    }

    /// Sets the header's bounds, for a writer that learns them from the records it wrote (the
    /// initial header holds whatever its start gave until `finish` rewrites it).
    pub fn set_bounds(&mut self, min: [f64; 3], max: [f64; 3]) {
        self.header.set_bounds(min, max);
    }

    /// `LasFileWriter::ready`, then the rename over the output.
    pub fn finish(self) -> Result<()> {
        self.ready()?.commit()
    }

    /// Finishes the points, writes the EVLRs, rewrites the header with the final layout and
    /// syncs the file, which the [`Ready`] renames over the output. On failure the temporary
    /// file is removed (by `TempFile`'s drop, whichever step failed).
    pub(crate) fn ready(mut self) -> Result<Ready> {
        // The header's counts are the caller's (an input's are carried over untouched): a file
        // with another number of records would be corrupt.
        if self.written != self.header.point_count {
            return Err(Error::Internal(format!(
                "{}: {} point records written but the header counts {}",
                self.tmp.output().display(),
                self.written,
                self.header.point_count
            )));
        }
        let tmp = self.tmp;
        let werr = |e: std::io::Error| tmp.error(e);
        let end_of_points = match &mut self.points {
            Points::Plain(w) => w.position(),
            Points::Laz(c) => {
                c.done().map_err(|e| laz_error(&tmp, e))?;
                c.get_mut().stream_position().map_err(werr)?
            }
        };
        let mut tail = Vec::new();
        for (i, v) in self.evlrs.iter().enumerate() {
            if Some(i) == self.waveform_evlr {
                self.layout.waveform_start = end_of_points + tail.len() as u64;
            }
            v.write_evlr(&mut tail);
        }
        if !self.evlrs.is_empty() && self.header.version.1 >= 4 {
            self.layout.evlr_start = end_of_points;
        }
        let file = match self.points {
            Points::Plain(mut w) => w.write_all(&tail).and_then(|_| w.into_file()),
            Points::Laz(c) => {
                let mut w = c.into_inner();
                w.write_all(&tail)
                    .and_then(|_| w.into_inner().map_err(|e| e.into_error()))
            }
        }
        .map_err(werr)?;
        file.write_all_at(&self.header.patched(&self.layout), 0)
            .map_err(werr)?;
        tmp.ready(file)
    }

    /// Removes the temporary file; the buffered records are discarded, not flushed.
    pub fn abandon(self) {
        if let Points::Laz(c) = self.points {
            drop(c.into_inner().into_parts());
        }
        drop(self.tmp);
    }
}

/// The I/O error (disk full, file too large) the laz compressor wraps: an output failure.
fn laz_io(e: std::io::Error) -> std::io::Error {
    if !e.get_ref().is_some_and(|i| i.is::<laz::LasZipError>()) {
        return e;
    }
    match e.into_inner().map(|i| i.downcast::<laz::LasZipError>()) {
        Some(Ok(z)) => match *z {
            laz::LasZipError::IoError(io) => laz_io(io),
            other => std::io::Error::other(other),
        },
        Some(Err(other)) => std::io::Error::other(other),
        None => std::io::Error::other("the LAZ compressor failed"),
    }
}

/// A laz compressor error: I/O fails the output; anything else (a layout it lacks) is ours.
fn laz_error(tmp: &TempFile, e: laz::LasZipError) -> Error {
    match e {
        laz::LasZipError::IoError(io) => tmp.error(laz_io(io)),
        other => Error::Internal(format!(
            "{}: LAZ compressor: {other}",
            tmp.output().display()
        )),
    }
}

impl PointSink for LasFileWriter {
    fn write_points(&mut self, records: &[u8]) -> Result<()> {
        self.write_records(records)
    }

    fn finish(self: Box<Self>) -> Result<Ready> {
        LasFileWriter::ready(*self)
    }

    fn abandon(self: Box<Self>) {
        LasFileWriter::abandon(*self)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::io::source::{LasSource, PointSource};

    /// A new LAS 1.2 file of `points` point format 0 records, centimetre coordinates (also
    /// the sink tests' input).
    pub(crate) fn spec(points: u64) -> LasFileSpec<'static> {
        LasFileSpec {
            origin: None,
            header: HeaderStart::New(NewHeader {
                minor: 2,
                system: "TEST",
                software: "tilecurv test",
                point_format: 0,
                record_length: 20,
                points,
                scale: [0.01; 3],
                offset: [0.0; 3],
                min: [0.0; 3],
                max: [0.0; 3],
            }),
            record_length: 20,
            vlrs: &[],
            evlrs: &[],
            extra_bytes: Vec::new(),
            provenance: "test run",
        }
    }

    /// A point format 0 record at integer coordinates `q`.
    pub(crate) fn record(q: [i32; 3]) -> Vec<u8> {
        let mut r: Vec<u8> = q.iter().flat_map(|v| v.to_le_bytes()).collect();
        r.resize(20, 0);
        r
    }

    #[test]
    fn writes_las_and_laz_with_late_bounds() {
        let dir = tempfile::tempdir().expect("temp dir");
        for name in ["a.las", "a.laz"] {
            let out = dir.path().join(name);
            let mut w = LasFileWriter::create(&out, spec(2)).expect("creates");
            w.write_records(&[record([1, 2, 3]), record([4, 5, 6])].concat())
                .expect("writes");
            w.set_bounds([0.01, 0.02, 0.03], [0.04, 0.05, 0.06]);
            w.finish().expect("finishes");
            let src = LasSource::open(&out).expect("reads back");
            assert_eq!(src.len(), 2);
            assert_eq!(src.header.compressed, name.ends_with(".laz"));
            assert_eq!(
                (src.header.min, src.header.max),
                ([0.01, 0.02, 0.03], [0.04, 0.05, 0.06])
            );
            let ids: Vec<(&str, u16)> = src
                .vlrs
                .iter()
                .map(|v| (v.user_id.as_str(), v.record_id))
                .collect();
            assert_eq!(ids[..2], [("LASF_Spec", 4), PROVENANCE], "{name}");
            let mut first = None;
            src.for_each_chunk(10, &mut |i, recs| {
                first = first.or(Some(src.decode(i, &recs[..20]).xyz));
                Ok(())
            })
            .expect("decodes");
            assert_eq!(first, Some([0.01, 0.02, 0.03]));
        }
    }

    #[test]
    fn several_extra_bytes_vlrs_are_written_as_one_in_place_of_the_first() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("eb.las");
        let col = |name: &str| {
            extra_bytes::encode(&extra_bytes::NewColumn::plain(
                name,
                extra_bytes::ScalarType::U8,
                "",
            ))
            .to_vec()
        };
        let vlrs = [
            extra_bytes::vlr(col("a")),
            Vlr::new("other", 7, "kept", vec![1, 2, 3]),
            extra_bytes::vlr(col("b")),
        ];
        let mut s = spec(1);
        s.record_length = 22;
        s.vlrs = &vlrs;
        s.extra_bytes = [col("a"), col("b")].concat();
        let mut w = LasFileWriter::create(&out, s).expect("creates");
        let mut r = record([1, 2, 3]);
        r.extend_from_slice(&[4, 5]);
        w.write_records(&r).expect("writes");
        w.finish().expect("finishes");
        let src = LasSource::open(&out).expect("reads back");
        let ids: Vec<(&str, u16)> = src
            .vlrs
            .iter()
            .map(|v| (v.user_id.as_str(), v.record_id))
            .collect();
        assert_eq!(ids, [("LASF_Spec", 4), ("other", 7), PROVENANCE]);
        let names: Vec<&str> = src.extra.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
    }

    /// Descriptors past a VLR's 65535 bytes go to a new EVLR in LAS 1.4, and are refused in
    /// LAS 1.2, which has no EVLRs.
    #[test]
    fn descriptors_past_a_vlr_go_to_an_evlr_in_las14_only() {
        let dir = tempfile::tempdir().expect("temp dir");
        let n = 342;
        let data: Vec<u8> = (0..n)
            .flat_map(|i| {
                let c =
                    extra_bytes::NewColumn::plain(format!("e{i}"), extra_bytes::ScalarType::U8, "");
                extra_bytes::encode(&c)
            })
            .collect();
        for minor in [2, 4] {
            let out = dir.path().join(format!("many{minor}.las"));
            let mut s = spec(1);
            if let HeaderStart::New(h) = &mut s.header {
                h.minor = minor;
                h.record_length = 20 + n as u16;
            }
            s.record_length = 20 + n as u16;
            s.extra_bytes = data.clone();
            let w = LasFileWriter::create(&out, s);
            if minor == 2 {
                let e = w.err().expect("refused").to_string();
                assert!(
                    e.contains("342 extra-bytes descriptors") && e.contains("no EVLRs"),
                    "{e}"
                );
                continue;
            }
            let mut w = w.expect("creates");
            let mut r = record([1, 2, 3]);
            r.resize(20 + n, 7);
            w.write_records(&r).expect("writes");
            w.finish().expect("finishes");
            let src = LasSource::open(&out).expect("reads back");
            assert!(!src.vlrs.iter().any(extra_bytes::is_extra_bytes));
            assert_eq!(src.evlrs.len(), 1);
            assert_eq!(src.extra.len(), n);
        }
    }

    #[test]
    fn a_wrong_record_count_or_an_abandon_leaves_nothing() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("short.las");
        let mut w = LasFileWriter::create(&out, spec(3)).expect("creates");
        w.write_records(&record([1, 2, 3])).expect("writes");
        assert!(matches!(w.finish(), Err(Error::Internal(_))));
        let mut w = LasFileWriter::create(&out, spec(1)).expect("creates");
        w.write_records(&record([1, 2, 3])).expect("writes");
        w.abandon();
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("lists").collect();
        assert!(left.is_empty(), "{left:?}");
    }
}
