//! Writing the output LAS/LAZ file: the input's header, VLRs and EVLRs carried over (a COPC
//! index is dropped: it would be stale), the extra-bytes VLR extended with tilecurv's columns,
//! a provenance VLR, and each input point record followed by its new column bytes. Written to a
//! temporary file beside the output, fsynced, and renamed over the output only by [`LasWriter::finish`].

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::columns::ColumnSet;
use crate::error::{Error, Result};
use crate::las::extra_bytes::{self, encode, encode_undocumented, parse, DESCRIPTOR_SIZE};
use crate::las::header::{OutputLayout, POINT_FORMAT_SIZES};
use crate::las::vlr::Vlr;
use crate::sink::PointSink;
use crate::source::{LasSource, PointSource};

/// User id and record id of the provenance VLR.
pub const PROVENANCE: (&str, u16) = ("tilecurv", 1);

/// Whether a path names a LAZ file (by extension; anything else that is .las is LAS).
pub fn output_is_laz(path: &Path) -> Result<bool> {
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

fn is_copc(v: &Vlr) -> bool {
    v.user_id == "copc"
}

/// The extra-bytes descriptors of the output: the input's (padded with an "undocumented"
/// descriptor if the input's records have more extra bytes than its VLR describes), then ours.
fn extra_bytes_payload(
    source: &LasSource,
    existing: Option<&Vlr>,
    cols: &ColumnSet,
) -> Result<Vec<u8>> {
    let mut data = existing.map(|v| v.data.clone()).unwrap_or_default();
    let described: usize = parse(&data)
        .map(|d| d.iter().map(|d| d.size).sum())
        .unwrap_or(0);
    let mut gap = source.header.extra_bytes_len() as usize - described;
    while gap > 0 {
        let n = gap.min(255);
        data.extend_from_slice(&encode_undocumented(n as u8));
        gap -= n;
    }
    for c in cols.columns() {
        if source
            .extra
            .iter()
            .any(|d| d.name.eq_ignore_ascii_case(&c.name))
        {
            return Err(Error::bad_input(source.path(), None, format!(
                "the input already has an extra dimension named {:?} (is it a tilecurv output?); process the original file instead", c.name)));
        }
        data.extend_from_slice(&encode(&c));
    }
    debug_assert_eq!(data.len() % DESCRIPTOR_SIZE, 0);
    Ok(data)
}

/// An output file being written.
pub struct LasWriter {
    tmp: PathBuf,
    output: PathBuf,
    header: crate::las::header::LasHeader,
    layout: OutputLayout,
    evlrs: Vec<Vlr>,
    waveform_evlr: Option<usize>,
    sink: Sink,
}

enum Sink {
    Plain(BufWriter<File>),
    Laz(Box<laz::ParLasZipCompressor<BufWriter<File>>>),
}

impl LasWriter {
    /// Creates the temporary output beside `output` and writes the header and VLRs.
    pub fn create(
        source: &LasSource,
        output: &Path,
        cols: &ColumnSet,
        provenance: &str,
    ) -> Result<Self> {
        let compressed = output_is_laz(output)?;
        let h = &source.header;
        let record_length =
            u16::try_from(h.record_length as usize + cols.record_size()).map_err(|_| {
                Error::bad_input(
                    source.path(),
                    Some(105),
                    format!(
                        "records of {} bytes plus {} new bytes exceed the LAS limit of 65535",
                        h.record_length,
                        cols.record_size()
                    ),
                )
            })?;
        // VLRs: the input's, minus the LAZ and COPC records (rebuilt or stale), with the
        // extra-bytes VLR extended in place (or added), then provenance and LASzip.
        let eb_in_evlr = source
            .evlrs
            .iter()
            .any(|(_, v)| extra_bytes::is_extra_bytes(v));
        let existing_eb = source
            .vlrs
            .iter()
            .chain(source.evlrs.iter().map(|(_, v)| v))
            .find(|v| extra_bytes::is_extra_bytes(v));
        let eb_data = extra_bytes_payload(source, existing_eb, cols)?;
        let mut vlrs: Vec<Vlr> = Vec::new();
        let mut placed = eb_in_evlr;
        for v in &source.vlrs {
            if v.is("laszip encoded", 22204) || is_copc(v) {
                continue;
            }
            if extra_bytes::is_extra_bytes(v) {
                vlrs.push(Vlr {
                    data: eb_data.clone(),
                    ..v.clone()
                });
                placed = true;
            } else {
                vlrs.push(v.clone());
            }
        }
        if !placed {
            vlrs.push(Vlr::new(
                extra_bytes::USER_ID,
                extra_bytes::RECORD_ID,
                "Extra Bytes Record",
                eb_data.clone(),
            ));
        }
        vlrs.push(Vlr::new(
            PROVENANCE.0,
            PROVENANCE.1,
            "tilecurv provenance",
            provenance.as_bytes().to_vec(),
        ));
        let laz_vlr = if compressed {
            let extra = record_length - POINT_FORMAT_SIZES[h.point_format as usize];
            let lv = laz::LazVlrBuilder::default()
                .with_point_format(h.point_format, extra)
                .map_err(|e| {
                    Error::Internal(format!(
                        "no LAZ layout for point format {}: {e}",
                        h.point_format
                    ))
                })?
                .with_fixed_chunk_size(50_000)
                .build();
            let mut data = Vec::new();
            lv.write_to(&mut data)
                .map_err(|e| Error::Internal(format!("LASzip VLR: {e}")))?;
            vlrs.push(Vlr::new("laszip encoded", 22204, "http://laszip.org", data));
            Some(lv)
        } else {
            None
        };
        let mut evlrs = Vec::new();
        let mut waveform_evlr = None;
        for (off, v) in &source.evlrs {
            if is_copc(v) {
                continue;
            }
            if *off == h.waveform_start {
                waveform_evlr = Some(evlrs.len());
            }
            if extra_bytes::is_extra_bytes(v) {
                evlrs.push(Vlr {
                    data: eb_data.clone(),
                    ..v.clone()
                });
            } else {
                evlrs.push(v.clone());
            }
        }
        let mut head = Vec::new();
        for v in &vlrs {
            v.write_vlr(&mut head)
                .map_err(|why| Error::bad_input(source.path(), None, why))?;
        }
        let offset = h.header_size as usize + head.len();
        let layout = OutputLayout {
            offset_to_point_data: u32::try_from(offset)
                .map_err(|_| Error::Internal("VLRs larger than 4 GiB".into()))?,
            num_vlrs: vlrs.len() as u32,
            compressed,
            record_length,
            evlr_start: 0,
            evlr_count: evlrs.len() as u32,
            waveform_start: 0,
        };
        let file_name = output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "output".into());
        let tmp =
            output.with_file_name(format!(".{file_name}.tilecurv-{}.tmp", std::process::id()));
        let file = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
        let mut w = BufWriter::with_capacity(4 << 20, file);
        w.write_all(&h.patched(&layout))
            .and_then(|_| w.write_all(&head))
            .map_err(|e| Error::write(&tmp, e))?;
        let sink = match laz_vlr {
            None => Sink::Plain(w),
            Some(lv) => Sink::Laz(Box::new(
                laz::ParLasZipCompressor::new(w, lv)
                    .map_err(|e| Error::Internal(format!("LAZ compressor: {e}")))?,
            )),
        };
        Ok(LasWriter {
            tmp,
            output: output.to_path_buf(),
            header: h.clone(),
            layout,
            evlrs,
            waveform_evlr,
            sink,
        })
    }
}

impl PointSink for LasWriter {
    fn write_points(&mut self, records: &[u8]) -> Result<()> {
        let r = match &mut self.sink {
            Sink::Plain(w) => w.write_all(records),
            Sink::Laz(c) => c.compress_many(records),
        };
        r.map_err(|e| Error::write(&self.tmp, e))
    }

    /// Finishes the points, writes the EVLRs, rewrites the header with the final layout, syncs
    /// the file and renames it over the output.
    fn finish(mut self: Box<Self>) -> Result<()> {
        let tmp = self.tmp.clone();
        let werr = |e: std::io::Error| Error::write(&tmp, e);
        let mut w = match self.sink {
            Sink::Plain(w) => w,
            Sink::Laz(mut c) => {
                c.done()
                    .map_err(|e| Error::Internal(format!("LAZ compressor: {e}")))?;
                c.into_inner()
            }
        };
        let end_of_points = w.stream_position().map_err(werr)?;
        let mut tail = Vec::new();
        let mut pos = end_of_points;
        for (i, v) in self.evlrs.iter().enumerate() {
            if Some(i) == self.waveform_evlr {
                self.layout.waveform_start = pos;
            }
            v.write_evlr(&mut tail);
            pos = end_of_points + tail.len() as u64;
        }
        if !self.evlrs.is_empty() && self.header.version.1 >= 4 {
            self.layout.evlr_start = end_of_points;
        }
        w.write_all(&tail).map_err(werr)?;
        w.seek(SeekFrom::Start(0)).map_err(werr)?;
        w.write_all(&self.header.patched(&self.layout))
            .map_err(werr)?;
        let file = w.into_inner().map_err(|e| werr(e.into_error()))?;
        file.sync_all().map_err(werr)?;
        drop(file);
        std::fs::rename(&self.tmp, &self.output).map_err(|e| Error::write(&self.output, e))?;
        if let Some(dir) = self.output.parent().filter(|d| !d.as_os_str().is_empty()) {
            // Make the rename durable; a directory that cannot be opened for sync is not fatal.
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }

    fn abandon(self: Box<Self>) {
        let tmp = self.tmp.clone();
        drop(self);
        let _ = std::fs::remove_file(tmp);
    }
}
