//! The extra-bytes VLR (LASF_Spec, record 4): parsing the descriptors of an input file, reading
//! a scalar extra dimension from a record, and encoding the descriptors of tilecurv's columns
//! (one scalar per descriptor, types 1 to 10 only: the tuple types 11 to 30 are deprecated).

use super::fields::{padded, trimmed};
use super::vlr::Vlr;

/// User id of the extra-bytes VLR.
pub const USER_ID: &str = "LASF_Spec";
/// Record id of the extra-bytes VLR.
pub const RECORD_ID: u16 = 4;
/// Size of one descriptor.
pub const DESCRIPTOR_SIZE: usize = 192;

/// Scalar data types of the extra-bytes specification (types 1 to 10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    /// u8
    U8 = 1,
    /// i8
    I8 = 2,
    /// u16
    U16 = 3,
    /// i16
    I16 = 4,
    /// u32
    U32 = 5,
    /// i32
    I32 = 6,
    /// u64
    U64 = 7,
    /// i64
    I64 = 8,
    /// f32
    F32 = 9,
    /// f64
    F64 = 10,
}

/// The first `N` bytes of `b` (which holds at least `N`).
#[inline(always)]
fn le<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(&b[..N]);
    a
}

impl ScalarType {
    fn from_code(code: u8) -> Option<Self> {
        use ScalarType::*;
        Some(match code {
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F32,
            10 => F64,
            _ => return None,
        })
    }

    /// Size in bytes.
    pub fn size(self) -> usize {
        use ScalarType::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }

    /// Decodes one value of this type from the first bytes of `b`, little-endian (`b` holds at
    /// least [`ScalarType::size`] bytes). Each type reads its own fixed width: the raster tap
    /// decodes every column of every output record here.
    #[inline(always)]
    pub fn decode(self, b: &[u8]) -> f64 {
        use ScalarType::*;
        match self {
            U64 => u64::from_le_bytes(le(b)) as f64,
            I64 => i64::from_le_bytes(le(b)) as f64,
            F32 => f32::from_le_bytes(le(b)) as f64,
            F64 => f64::from_le_bytes(le(b)),
            _ => self.decode_integer(b) as f64,
        }
    }

    /// [`ScalarType::decode`] of an integer type of at most 32 bits, as the integer (without
    /// the round trip through f64 that cost as much as the rest of binning a value); 0 for the
    /// other types.
    #[inline(always)]
    pub fn decode_integer(self, b: &[u8]) -> i64 {
        use ScalarType::*;
        match self {
            U8 => b[0] as i64,
            I8 => b[0] as i8 as i64,
            U16 => u16::from_le_bytes(le(b)) as i64,
            I16 => i16::from_le_bytes(le(b)) as i64,
            U32 => u32::from_le_bytes(le(b)) as i64,
            I32 => i32::from_le_bytes(le(b)) as i64,
            U64 | I64 | F32 | F64 => 0,
        }
    }

    /// Whether the type is a signed integer.
    fn signed(self) -> bool {
        use ScalarType::*;
        matches!(self, I8 | I16 | I32 | I64)
    }

    /// The 8 bytes of a descriptor's no-data, min or max field holding `v` of this type: an
    /// i64 for signed types, a u64 for unsigned ones, an f64 for floats.
    pub fn upcast_encode(self, v: f64) -> [u8; 8] {
        use ScalarType::*;
        match self {
            F32 | F64 => v.to_le_bytes(),
            _ if self.signed() => (v as i64).to_le_bytes(),
            _ => (v as u64).to_le_bytes(),
        }
    }

    /// The value of a descriptor's 8-byte no-data, min or max field for this type.
    pub fn upcast_decode(self, b: &[u8]) -> f64 {
        use ScalarType::*;
        let a: [u8; 8] = b.get(..8).and_then(|s| s.try_into().ok()).unwrap_or([0; 8]);
        match self {
            F32 | F64 => f64::from_le_bytes(a),
            _ if self.signed() => i64::from_le_bytes(a) as f64,
            _ => u64::from_le_bytes(a) as f64,
        }
    }
}

/// One parsed descriptor of an input file.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptor {
    /// Dimension name.
    pub name: String,
    /// Raw data type code (0 = undocumented bytes, 1-10 scalars, 11-30 deprecated tuples).
    pub data_type: u8,
    /// Byte offset within the extra bytes of a record.
    pub offset: usize,
    /// Size in bytes.
    pub size: usize,
    /// Scale for scalar types (1 when absent).
    pub scale: f64,
    /// Offset for scalar types (0 when absent).
    pub value_offset: f64,
    /// The raw value that marks a missing value, when the descriptor declares one (its
    /// options bit 0), as an f64 (every i8-i32, u8-u32 and float no-data value is exact).
    pub no_data: Option<f64>,
}

impl Descriptor {
    /// The scalar type, if this is a scalar dimension (types 1-10).
    pub fn scalar(&self) -> Option<ScalarType> {
        ScalarType::from_code(self.data_type)
    }

    /// Reads this dimension's value (scale and offset applied) from a record's extra bytes;
    /// NaN when the raw value is the declared no-data value.
    pub fn read(&self, extra: &[u8]) -> Option<f64> {
        self.read_as(self.scalar()?, extra)
    }

    /// [`Descriptor::read`] for a dimension of the scalar type `t` (its [`Descriptor::scalar`]):
    /// inlined, so that a loop over many records with one known type compiles to that type's
    /// decoding alone.
    #[inline(always)]
    pub fn read_as(&self, t: ScalarType, extra: &[u8]) -> Option<f64> {
        let raw = t.decode(extra.get(self.offset..self.offset + t.size())?);
        if self.no_data == Some(raw) {
            return Some(f64::NAN);
        }
        Some(raw * self.scale + self.value_offset)
    }

    /// The declared no-data value as the raw integer [`ScalarType::decode_integer`] gives
    /// for it, when it is one (of at most 32 bits): the value [`Descriptor::read_as`] takes
    /// as no-data, for a reader that compares integers rather than each value as an f64.
    pub fn no_data_integer(&self) -> Option<i64> {
        (self.no_data)
            .filter(|v| v.fract() == 0.0 && v.abs() <= u32::MAX as f64)
            .map(|v| v as i64)
    }
}

/// Parses the descriptors of an extra-bytes VLR payload. Returns an error message when the
/// payload is malformed; unknown reserved type codes are sized by their options byte as the
/// specification says for type 0.
pub fn parse(data: &[u8]) -> Result<Vec<Descriptor>, String> {
    if !data.len().is_multiple_of(DESCRIPTOR_SIZE) {
        return Err(format!(
            "extra-bytes VLR is {} bytes, not a multiple of {DESCRIPTOR_SIZE}",
            data.len()
        ));
    }
    let mut out = Vec::new();
    let mut offset = 0usize;
    for d in data.chunks_exact(DESCRIPTOR_SIZE) {
        let data_type = d[2];
        let options = d[3];
        let name = trimmed(&d[4..36]);
        let size = match data_type {
            0 => options as usize,
            1..=10 => ScalarType::from_code(data_type)
                .map(|t| t.size())
                .unwrap_or(0),
            11..=30 => {
                let base = ScalarType::from_code((data_type - 1) % 10 + 1)
                    .map(|t| t.size())
                    .unwrap_or(0);
                base * (((data_type - 1) / 10) as usize + 1)
            }
            other => {
                return Err(format!(
                    "extra dimension {name:?} has unknown data type {other}"
                ))
            }
        };
        let f = |o: usize| f64::from_le_bytes(d[o..o + 8].try_into().unwrap_or([0; 8]));
        let scale = if options & OPTION_SCALE != 0 {
            f(112)
        } else {
            1.0
        };
        let value_offset = if options & OPTION_OFFSET != 0 {
            f(136)
        } else {
            0.0
        };
        let no_data = ScalarType::from_code(data_type)
            .filter(|_| options & OPTION_NO_DATA != 0)
            .map(|t| t.upcast_decode(&d[40..48]));
        out.push(Descriptor {
            name,
            data_type,
            offset,
            size,
            scale,
            value_offset,
            no_data,
        });
        offset += size;
    }
    Ok(out)
}

/// A new column that tilecurv adds, for its descriptor.
#[derive(Debug, Clone, PartialEq)]
pub struct NewColumn {
    /// Dimension name (at most 32 bytes).
    pub name: String,
    /// Storage type.
    pub ty: ScalarType,
    /// Human-readable description with its unit (at most 32 bytes).
    pub description: String,
    /// Scale and offset of a scaled column (the value is raw * scale + offset).
    pub scaling: Option<(f64, f64)>,
    /// The raw value that marks a missing value, declared in the descriptor.
    pub no_data: Option<f64>,
}

impl NewColumn {
    /// A column of `ty` with no scale, offset or no-data value.
    pub fn plain(name: impl Into<String>, ty: ScalarType, description: impl Into<String>) -> Self {
        NewColumn {
            name: name.into(),
            ty,
            description: description.into(),
            scaling: None,
            no_data: None,
        }
    }
}

/// Options bit: the no-data field (bytes 40-47) holds the raw value of a missing value.
pub const OPTION_NO_DATA: u8 = 0x01;
/// Options bit: the scale field (bytes 112-119) applies.
pub const OPTION_SCALE: u8 = 0x08;
/// Options bit: the offset field (bytes 136-143) applies.
pub const OPTION_OFFSET: u8 = 0x10;

/// Encodes one scalar descriptor (LAS 1.4 R15 table 24): name, type, description, and for a
/// scaled column its scale and offset, and its no-data value, each with its options bit (the
/// no-data value upcast to the field's 8 bytes: i64 for signed types, u64 for unsigned, f64
/// for floats). No min or max. Float columns declare no no-data NaN, because readers disagree
/// on it: the flag column says when a value is undefined.
pub fn encode(col: &NewColumn) -> [u8; DESCRIPTOR_SIZE] {
    let mut d = [0u8; DESCRIPTOR_SIZE];
    d[2] = col.ty as u8;
    let mut options = 0;
    if let Some(v) = col.no_data {
        options |= OPTION_NO_DATA;
        d[40..48].copy_from_slice(&col.ty.upcast_encode(v));
    }
    if let Some((scale, offset)) = col.scaling {
        options |= OPTION_SCALE | OPTION_OFFSET;
        d[112..120].copy_from_slice(&scale.to_le_bytes());
        d[136..144].copy_from_slice(&offset.to_le_bytes());
    }
    d[3] = options;
    d[4..36].copy_from_slice(&padded::<32>(&col.name));
    d[160..192].copy_from_slice(&padded::<32>(&col.description));
    d
}

/// A type-0 descriptor covering `n` undocumented extra bytes, so that columns appended after
/// them are found at the right offset.
pub fn encode_undocumented(n: u8) -> [u8; DESCRIPTOR_SIZE] {
    let mut d = [0u8; DESCRIPTOR_SIZE];
    d[2] = 0;
    d[3] = n;
    d[4..36].copy_from_slice(&padded::<32>("undocumented extra bytes"));
    d
}

/// An extra-bytes VLR holding the encoded descriptors `data`.
pub fn vlr(data: Vec<u8>) -> Vlr {
    Vlr::new(USER_ID, RECORD_ID, "Extra Bytes Record", data)
}

/// Whether `v` is an extra-bytes VLR or EVLR.
pub fn is_extra_bytes(v: &Vlr) -> bool {
    v.is(USER_ID, RECORD_ID)
}

/// The descriptors of every extra-bytes record among `records` (a file's VLRs, then its EVLRs),
/// concatenated in that order: one payload describing the records' extra bytes from the first
/// byte. Some writers split the descriptors over two records, while readers (laspy, PDAL) take
/// one, so a file must be read through all of them and written with exactly one. Fails when a
/// record's payload is not a whole number of descriptors, since the concatenation would then
/// misplace every descriptor after it.
pub fn merged_payload<'a>(records: impl IntoIterator<Item = &'a Vlr>) -> Result<Vec<u8>, String> {
    let mut data = Vec::new();
    for (i, v) in records
        .into_iter()
        .filter(|v| is_extra_bytes(v))
        .enumerate()
    {
        if !v.data.len().is_multiple_of(DESCRIPTOR_SIZE) {
            return Err(format!(
                "extra-bytes record {} is {} bytes, not a multiple of {DESCRIPTOR_SIZE}",
                i + 1,
                v.data.len()
            ));
        }
        data.extend_from_slice(&v.data);
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scaled i32 column with a no-data value, byte for byte as LAS 1.4 R15 table 24 places
    /// the fields, and parsed back: the no-data raw value reads as NaN, others scaled.
    #[test]
    fn scaled_columns_declare_scale_offset_and_no_data() {
        let col = NewColumn {
            scaling: Some((0.25, 0.0)),
            no_data: Some(i32::MIN as f64),
            ..NewColumn::plain("H", ScalarType::I32, "mean curvature (1/m)")
        };
        let d = encode(&col);
        assert_eq!(d[2], 6, "i32");
        assert_eq!(d[3], 0x01 | 0x08 | 0x10);
        assert_eq!(&d[4..6], b"H\0");
        assert_eq!(d[40..48], (i32::MIN as i64).to_le_bytes());
        assert_eq!(d[112..120], 0.25f64.to_le_bytes());
        assert_eq!(d[136..144], 0.0f64.to_le_bytes());
        assert!(d[48..112].iter().all(|&b| b == 0), "no min, no max");
        let p = parse(&d).expect("parses");
        assert_eq!(
            (p[0].scale, p[0].value_offset, p[0].no_data, p[0].size),
            (0.25, 0.0, Some(i32::MIN as f64), 4)
        );
        assert_eq!(p[0].read(&(-6i32).to_le_bytes()), Some(-1.5));
        assert!(p[0]
            .read(&i32::MIN.to_le_bytes())
            .is_some_and(|v| v.is_nan()));
        let plain = parse(&encode(&NewColumn::plain("f", ScalarType::F32, ""))).expect("parses");
        assert_eq!(
            (
                plain[0].scale,
                plain[0].no_data,
                encode(&NewColumn::plain("f", ScalarType::F32, ""))[3]
            ),
            (1.0, None, 0)
        );
    }
}
