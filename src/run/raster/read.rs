//! Reading the raster columns of point records ([`Reader`]) and binning them ([`Binner`]):
//! the one path of `raster`'s inputs and of `process --raster`'s output records.

use crate::core::raster::{Integers, Stat, UNDEFINED};
use crate::error::{Error, Result};
use crate::io::las::extra_bytes::{Descriptor, ScalarType};
use crate::io::las::header::POINT_FORMAT_SIZES;
use crate::io::ply::PlyNames;
use crate::io::raster::{RasterColumn, Rasterizer};
use crate::io::source::{PointSource, Property, SourceLayout};

/// Where a column's value is in a record.
pub(super) enum Reader {
    /// A LAS extra dimension (its no-data value gives NaN).
    Extra { at: usize, d: Descriptor },
    /// Any other property.
    Property(Property),
}

impl Reader {
    /// How the column's values are integers: a LAS extra dimension of an integer type of at
    /// most 32 bits with a finite scale and offset (those); None for any other.
    fn integers(&self) -> Option<Integers> {
        use ScalarType::*;
        match self {
            Reader::Extra { d, .. }
                if matches!(d.scalar()?, U8 | I8 | U16 | I16 | U32 | I32)
                    && d.scale.is_finite()
                    && d.value_offset.is_finite() =>
            {
                Some(Integers {
                    scale: d.scale,
                    offset: d.value_offset,
                })
            }
            _ => None,
        }
    }

    /// The oriented integer ([`Integers::oriented`]) of each record of `records` (`row` bytes
    /// each) into column `c` of `ints` (rows of `width`), [`UNDEFINED`] where it is missing
    /// or no-data. For a reader with [`Reader::integers`] (any other gives [`UNDEFINED`]).
    fn integer_column(
        &self,
        records: &[u8],
        row: usize,
        ints: &mut [i64],
        (c, width): (usize, usize),
    ) {
        let (Reader::Extra { at, d }, Some(ints_of)) = (self, self.integers()) else {
            return each(records, row, ints, (c, width), |_| UNDEFINED);
        };
        // The no-data integer (UNDEFINED, which no integer read is, if none) and the sign that
        // orients the integers, found once: comparing each value as an f64 (`read_as`) cost
        // 10 instructions a value more.
        let no_data = d.no_data_integer().unwrap_or(UNDEFINED);
        let sign = ints_of.oriented(1);
        let start = at + d.offset;
        let read = |rec: &[u8], t: ScalarType| match rec.get(start..start + t.size()) {
            Some(b) => {
                let raw = t.decode_integer(b);
                if raw == no_data {
                    UNDEFINED
                } else {
                    sign * raw
                }
            }
            None => UNDEFINED,
        };
        // The types tilecurv writes in a loop of their own; the others as read.
        let place = (c, width);
        match d.scalar() {
            Some(ScalarType::I32) => each(records, row, ints, place, |r| read(r, ScalarType::I32)),
            Some(ScalarType::I16) => each(records, row, ints, place, |r| read(r, ScalarType::I16)),
            Some(t) => each(records, row, ints, place, |r| read(r, t)),
            None => each(records, row, ints, place, |_| UNDEFINED),
        }
    }

    /// The value of each record of `records` (`row` bytes each) into column `c` of `values`
    /// (rows of `width`), NaN where it is missing or no-data.
    fn column(&self, records: &[u8], row: usize, values: &mut [f32], (c, width): (usize, usize)) {
        let place = (c, width);
        let (at, d) = match self {
            Reader::Property(p) => return each(records, row, values, place, |r| p.value(r) as f32),
            Reader::Extra { at, d } => (*at, d),
        };
        let extra = |r: &[u8], t| {
            r.get(at..)
                .and_then(|e| d.read_as(t, e))
                .unwrap_or(f64::NAN) as f32
        };
        // The type fixed in each loop (the types tilecurv writes, and f64); any other as read.
        match d.scalar() {
            Some(ScalarType::I32) => {
                each(records, row, values, place, |r| extra(r, ScalarType::I32))
            }
            Some(ScalarType::I16) => {
                each(records, row, values, place, |r| extra(r, ScalarType::I16))
            }
            Some(ScalarType::F32) => {
                each(records, row, values, place, |r| extra(r, ScalarType::F32))
            }
            Some(ScalarType::F64) => {
                each(records, row, values, place, |r| extra(r, ScalarType::F64))
            }
            Some(t) => each(records, row, values, place, |r| extra(r, t)),
            None => each(records, row, values, place, |_| f32::NAN),
        }
    }
}

/// `read` of each record of `records` (`row` bytes each) into column `c` of `values` (rows of
/// `width`): a loop for each column and stored type, made by the closure it is given.
#[inline(always)]
fn each<T>(
    records: &[u8],
    row: usize,
    values: &mut [T],
    (c, width): (usize, usize),
    read: impl Fn(&[u8]) -> T,
) {
    for (rec, v) in records
        .chunks_exact(row)
        .zip(values.chunks_exact_mut(width))
    {
        v[c] = read(rec);
    }
}

/// The reader of the column `name` in `s`, as [`spelled`] finds it.
pub(super) fn reader(s: &dyn PointSource, name: &str) -> Option<Reader> {
    let name = spelled(s, name)?;
    if let SourceLayout::Las(p) = s.layout() {
        let base = POINT_FORMAT_SIZES[p.header.point_format as usize] as usize;
        if let Some(d) = p.extra.iter().find(|d| d.name == name) {
            return d.scalar().map(|_| Reader::Extra {
                at: base,
                d: d.clone(),
            });
        }
    }
    s.properties()
        .into_iter()
        .find(|p| p.name == name)
        .map(Reader::Property)
}

/// The name of `s`'s column `name` as the file spells it: the column of exactly that name,
/// else the first whose name differs only in case (`Z` for `z`, `h` for `H` in a file
/// without an `H`), else the same for the name a PLY output gives the column by default
/// (`scalar_H` for `H`, `nx` for `NormalX`).
pub(super) fn spelled(s: &dyn PointSource, name: &str) -> Option<String> {
    let names = column_names(s);
    let find = |name: &str| {
        let exact = names.iter().find(|n| *n == name);
        exact
            .or_else(|| names.iter().find(|n| n.eq_ignore_ascii_case(name)))
            .cloned()
    };
    find(name).or_else(|| find(&PlyNames::CloudCompare.name(name)))
}

/// The reader of the column `name` of a later input `s`, or the error that it lacks one the
/// first input has.
pub(super) fn reader_of_later(s: &dyn PointSource, name: &str) -> Result<Reader> {
    reader(s, name).ok_or_else(|| {
        Error::Usage(format!(
            "{} has no column {name:?} (the first input has it); it has: {}",
            s.path().display(),
            column_names(s).join(", ")
        ))
    })
}

/// The names of the columns of `s`.
pub(super) fn column_names(s: &dyn PointSource) -> Vec<String> {
    s.properties().into_iter().map(|p| p.name).collect()
}

/// Sets [`RasterColumn::integers`] of each of `columns` whose values are integers of one
/// scale and offset in every input (`readers`: a reader a column, for each input) when `stat`
/// tallies integers: those columns' cells then tally them instead of keeping every value. An
/// aspect's mean is circular: its values are kept.
pub(super) fn tally_integers(columns: &mut [RasterColumn], readers: &[Vec<Reader>], stat: Stat) {
    for (c, column) in columns.iter_mut().enumerate() {
        let mut each = readers.iter().map(|r| r.get(c).and_then(Reader::integers));
        let first = each.next().flatten();
        let same = each.all(|i| i.is_some() && i == first);
        column.integers = first.filter(|_| same && stat.tallies() && !column.angle);
    }
}

/// Reads points' raster values from their records and bins them: the one path of `raster`'s
/// inputs and of `process --raster`'s output records.
pub(super) struct Binner {
    /// Per raster column, where its value is in a record and how it is stored, and whether
    /// it is read as integers ([`RasterColumn::integers`]).
    readers: Vec<(Reader, bool)>,
    /// The values of the points being binned, a row each: the columns not read as integers.
    floats: Vec<f32>,
    /// Their integers, a row each: the columns read as integers, then z as an integer.
    ints: Vec<i64>,
    /// Their coordinates.
    xyz: Vec<[f64; 3]>,
}

impl Binner {
    /// The binner of the columns of `r`'s request with `readers`, one each.
    pub(super) fn new(readers: Vec<Reader>, r: &Rasterizer) -> Self {
        let columns = r.request().columns.iter();
        Binner {
            readers: (readers.into_iter().zip(columns))
                .map(|(rd, c)| (rd, c.integers.is_some()))
                .collect(),
            floats: Vec::new(),
            ints: Vec::new(),
            xyz: Vec::new(),
        }
    }

    /// Bins the points of `s` whose records, `row` bytes each (the source's record first, then
    /// any columns an output added), are `records`; the first is point `first`. Column by
    /// column over [`Binner::BATCH`] points at a time, each column in a loop made for its
    /// stored type: point by point, choosing the type of every value again cost more than
    /// binning it. `what` names a point in an error.
    pub(super) fn bin_all(
        &mut self,
        s: &dyn PointSource,
        (first, records, row): (u64, &[u8], usize),
        r: &mut Rasterizer,
        what: &dyn Fn(u64) -> String,
    ) -> Result<()> {
        let ni = self.readers.iter().filter(|(_, ints)| *ints).count();
        let (nf, wi) = (self.readers.len() - ni, ni + 1);
        for (b, batch) in records.chunks(Self::BATCH * row).enumerate() {
            let first = first + (b * Self::BATCH) as u64;
            let n = batch.len() / row;
            self.floats.resize(n * nf, 0.0);
            self.ints.resize(n * wi, 0);
            self.xyz.clear();
            s.coordinates(first, batch, row, &mut self.xyz);
            for (p, v) in self.xyz.iter().zip(self.ints.chunks_exact_mut(wi)) {
                v[ni] = Rasterizer::z_integer(p[2]);
            }
            let (mut fc, mut ic) = (0, 0);
            for (rd, ints) in &self.readers {
                if *ints {
                    rd.integer_column(batch, row, &mut self.ints, (ic, wi));
                    ic += 1;
                } else {
                    rd.column(batch, row, &mut self.floats, (fc, nf));
                    fc += 1;
                }
            }
            for (i, p) in self.xyz.iter().enumerate() {
                let values = (
                    &self.floats[i * nf..(i + 1) * nf],
                    &self.ints[i * wi..(i + 1) * wi],
                );
                r.push(p[0], p[1], values, &|| what(first + i as u64))?;
            }
        }
        Ok(())
    }

    /// Points decoded at a time: their records (about 100 bytes each with the terrain columns)
    /// and values stay in the first-level cache between the columns (4096 did not: a miss for
    /// every record in every column's loop, 12 a point more than a run without rasters).
    const BATCH: usize = 256;
}
