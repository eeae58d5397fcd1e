//! The columns tilecurv adds to every point: their names, the groups `--columns` picks them by,
//! their descriptions (with the file's unit) and how a tile result file stores them. One
//! definition used by the result files, the writers and the tests. Result files hold every
//! value as an f32 (an f64 for `--f64` outputs: [`ColumnSet::wide`]), whatever the output's
//! encoding, which is chosen when the outputs are written ([`output`]: scaled integers, f32 or
//! f64).

mod layout;
pub(crate) mod output;
mod terrain;
mod transcode;

pub(crate) use layout::ResultLayout;
use layout::MAX_STORED;
pub(crate) use terrain::TerrainValue;
pub(crate) use transcode::{Stored, Transcoder};

use crate::core::compute::PointResult;
use crate::core::estimate::{EstimatorKind, EstimatorParams, ExtraColumn, MAX_EXTRA};

/// Name of the quality-flag column.
pub(crate) const FLAGS_NAME: &str = "CurvatureFlags";

/// How the new columns are stored in a LAS/LAZ output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColumnType {
    /// Scaled integers (the default): unit vectors as i16 at 1/32767, curvatures as i32 at a
    /// step chosen from the data ([`output`]). A PLY output, which has no scale field, gets
    /// f32 instead.
    #[default]
    Scaled,
    /// 32-bit floats (`--f32`).
    F32,
    /// 64-bit floats (`--f64`).
    F64,
}

impl ColumnType {
    /// The name the manifest and the provenance use.
    pub fn name(self) -> &'static str {
        match self {
            ColumnType::Scaled => "scaled",
            ColumnType::F32 => "f32",
            ColumnType::F64 => "f64",
        }
    }

    /// The type named `name` ([`ColumnType::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        [ColumnType::Scaled, ColumnType::F32, ColumnType::F64]
            .into_iter()
            .find(|t| t.name() == name)
    }
}

/// A group of new columns, as `--columns` names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    /// NormalX, NormalY, NormalZ.
    Normals,
    /// Mean curvature.
    H,
    /// Gaussian curvature.
    K,
    /// Smaller principal curvature.
    K1,
    /// Larger principal curvature.
    K2,
    /// d1x, d1y, d1z, d2x, d2y, d2z: the principal directions.
    Directions,
    /// The estimator's extra values (the VCM's SharpFeature, VcmNormalX/Y/Z).
    Features,
    /// ScaleK, ScaleFlags: the scale `-k auto` chose (always written with it, never without).
    Scale,
    /// CurvatureFlags.
    Flags,
    /// One terrain column (never [`TerrainValue::Flags`], which comes with any of them).
    Terrain(TerrainValue),
}

/// The word `--columns` takes for every terrain group at once.
pub(crate) const TERRAIN_WORD: &str = "terrain";

impl Group {
    /// Every group, in record order. The terrain groups come after the flags, so that an output
    /// without them has the bytes it had before they existed.
    pub const ALL: [Group; 16] = [
        Group::Normals,
        Group::H,
        Group::K,
        Group::K1,
        Group::K2,
        Group::Directions,
        Group::Features,
        Group::Scale,
        Group::Flags,
        Group::Terrain(TerrainValue::Profile),
        Group::Terrain(TerrainValue::Tangential),
        Group::Terrain(TerrainValue::Plan),
        Group::Terrain(TerrainValue::ShapeIndex),
        Group::Terrain(TerrainValue::Curvedness),
        Group::Terrain(TerrainValue::Slope),
        Group::Terrain(TerrainValue::Aspect),
    ];

    /// The terrain groups (`--columns terrain`, algorithms.md 10): the tail of [`Group::ALL`].
    pub fn terrain() -> impl Iterator<Item = Group> {
        TerrainValue::ALL
            .into_iter()
            .filter_map(TerrainValue::group)
    }

    /// The name `--columns` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Group::Normals => "normals",
            Group::H => "H",
            Group::K => "K",
            Group::K1 => "k1",
            Group::K2 => "k2",
            Group::Directions => "directions",
            Group::Features => "features",
            Group::Scale => "scale",
            Group::Flags => "flags",
            Group::Terrain(t) => t.word(),
        }
    }

    /// Its bit in a [`ColumnChoice`]; none for a group outside [`Group::ALL`] (the terrain
    /// flags, which no `--columns` name chooses).
    fn bit(self) -> u32 {
        Group::ALL
            .iter()
            .position(|&g| g == self)
            .map_or(0, |i| 1 << i)
    }
}

/// The groups of columns a run writes (`--columns`), always in the record order of
/// [`Group::ALL`] whatever the order they were named in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ColumnChoice(u32);

impl Default for ColumnChoice {
    /// H, K, flags: the columns whose LAZ output stays within 2x its LAZ input on forest TLS
    /// (bcts_1: 1.95x; with normals, k1 and k2 4.2x), README "Compact columns".
    fn default() -> Self {
        [Group::H, Group::K, Group::Flags]
            .into_iter()
            .fold(ColumnChoice(0), ColumnChoice::with)
    }
}

impl ColumnChoice {
    /// Whether the group is chosen.
    pub fn has(self, g: Group) -> bool {
        self.0 & g.bit() != 0
    }

    /// This choice with `g` added.
    pub fn with(self, g: Group) -> Self {
        ColumnChoice(self.0 | g.bit())
    }

    /// This choice with `g` added when `on`.
    pub fn with_if(self, on: bool, g: Group) -> Self {
        match on {
            true => self.with(g),
            false => self,
        }
    }

    /// This choice without `g`.
    pub fn without(self, g: Group) -> Self {
        ColumnChoice(self.0 & !g.bit())
    }

    /// Whether any terrain group is chosen (then TerrainFlags is written too).
    pub fn has_terrain(self) -> bool {
        Group::terrain().any(|g| self.has(g))
    }

    /// This choice without the column holding `v`: its group, or every terrain group for
    /// TerrainFlags (written with any of them).
    pub fn without_value(self, v: Value) -> Self {
        match v {
            Value::Terrain(TerrainValue::Flags) => {
                Group::terrain().fold(self, ColumnChoice::without)
            }
            v => self.without(v.group()),
        }
    }

    /// Parses a comma-separated list of group names (any case: the lower-case names are all
    /// different); an unknown or missing name is an error that lists the valid ones.
    pub fn parse(list: &str) -> Result<Self, String> {
        let valid = || {
            Group::ALL
                .iter()
                .map(|g| g.name())
                .chain([TERRAIN_WORD])
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut c = ColumnChoice(0);
        for word in list.split(',').map(str::trim) {
            if word.is_empty() {
                return Err(format!(
                    "{list:?} has an empty column name: give a comma-separated list of {}",
                    valid()
                ));
            }
            if word.eq_ignore_ascii_case(TERRAIN_WORD) {
                c = Group::terrain().fold(c, ColumnChoice::with);
                continue;
            }
            let g = Group::ALL
                .into_iter()
                .find(|g| g.name().eq_ignore_ascii_case(word))
                .ok_or_else(|| format!("unknown column {word:?}: the columns are {}", valid()))?;
            c = c.with(g);
        }
        Ok(c)
    }
}

impl std::fmt::Display for ColumnChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = Group::ALL
            .into_iter()
            .filter(|&g| self.has(g))
            .map(Group::name)
            .collect();
        write!(f, "{}", names.join(","))
    }
}

/// The value of a point's result a column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Value {
    /// A component of the normal.
    Normal(usize),
    /// Mean curvature.
    H,
    /// Gaussian curvature.
    K,
    /// Smaller principal curvature.
    K1,
    /// Larger principal curvature.
    K2,
    /// A component of the direction of k1.
    D1(usize),
    /// A component of the direction of k2.
    D2(usize),
    /// The estimator's extra value of this index.
    Extra(usize),
    /// The K of the rung `-k auto` chose.
    ScaleK,
    /// How `-k auto` chose it (core::scale::scale_flags).
    ScaleFlags,
    /// The quality flags.
    Flags,
    /// A terrain value (algorithms.md 10).
    Terrain(TerrainValue),
}

impl Value {
    /// This value of `r` (the flags as a number). Inlined, so that a loop over points for one
    /// known value reads its field alone.
    #[inline(always)]
    pub fn get(self, r: &PointResult) -> f64 {
        let c = &r.curvature;
        match self {
            Value::Normal(i) => r.normal[i],
            Value::H => c.h,
            Value::K => c.k,
            Value::K1 => c.k1,
            Value::K2 => c.k2,
            Value::D1(i) => c.d1[i],
            Value::D2(i) => c.d2[i],
            Value::Extra(i) => r.extra[i],
            Value::ScaleK => r.scale as f64,
            Value::ScaleFlags => r.scale_flags as f64,
            Value::Flags => c.flags as f64,
            Value::Terrain(t) => t.get(&r.terrain),
        }
    }

    /// Whether a result file stores this value as a byte after the curvature flags (it is a
    /// set of flags, below 256), not as a number.
    pub fn is_flag_byte(self) -> bool {
        matches!(
            self,
            Value::ScaleFlags | Value::Flags | Value::Terrain(TerrainValue::Flags)
        )
    }

    /// The `--columns` group of the column holding this value.
    pub fn group(self) -> Group {
        match self {
            Value::Normal(_) => Group::Normals,
            Value::H => Group::H,
            Value::K => Group::K,
            Value::K1 => Group::K1,
            Value::K2 => Group::K2,
            Value::D1(_) | Value::D2(_) => Group::Directions,
            Value::Extra(_) => Group::Features,
            Value::ScaleK | Value::ScaleFlags => Group::Scale,
            Value::Flags => Group::Flags,
            Value::Terrain(t) => Group::Terrain(t),
        }
    }

    pub(super) fn set(self, r: &mut PointResult, v: f64) {
        let c = &mut r.curvature;
        match self {
            Value::Normal(i) => r.normal[i] = v,
            Value::H => c.h = v,
            Value::K => c.k = v,
            Value::K1 => c.k1 = v,
            Value::K2 => c.k2 = v,
            Value::D1(i) => c.d1[i] = v,
            Value::D2(i) => c.d2[i] = v,
            Value::Extra(i) => r.extra[i] = v,
            Value::ScaleK => r.scale = v as u16,
            Value::ScaleFlags => r.scale_flags = v as u8,
            Value::Flags => c.flags = v as u8,
            Value::Terrain(t) => t.set(&mut r.terrain, v),
        }
    }
}

/// One new column: its name, description and value.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The LAS dimension name.
    pub name: &'static str,
    /// The description, with its unit (at most 32 bytes: a LAS extra-bytes description).
    pub description: String,
    /// What it holds.
    pub value: Value,
}

/// The name of every column tilecurv can write (every group, every estimator's extra
/// columns): what an output's provenance record is taken to claim when it does not list its
/// columns (outputs of a tilecurv older than the list).
pub(crate) fn every_name() -> Vec<&'static str> {
    let mut extra: Vec<ExtraColumn> = Vec::new();
    for kind in EstimatorKind::ALL {
        for c in kind.build(&EstimatorParams::default()).extra_columns() {
            if !extra.iter().any(|e| e.name == c.name) {
                extra.push(*c);
            }
        }
    }
    let set = ColumnSet {
        choice: Group::ALL
            .into_iter()
            .fold(ColumnChoice(0), ColumnChoice::with),
        extra,
        unit: String::new(),
        wide: false,
    };
    set.columns().into_iter().map(|c| c.name).collect()
}

/// The new columns of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSet {
    /// The groups written; without [`Group::Normals`] when the input's own NormalX/Y/Z are
    /// used (they are kept as they are).
    pub choice: ColumnChoice,
    /// The estimator's extra values (with [`Group::Features`]: its declared
    /// [`Estimator::extra_columns`](crate::core::estimate::Estimator::extra_columns), e.g. the
    /// VCM's `SharpFeature`, `VcmNormalX/Y/Z`); empty otherwise.
    pub extra: Vec<ExtraColumn>,
    /// Unit symbol of the coordinates, for the descriptions ("m", "ft", or "unit").
    pub unit: String,
    /// Whether result files hold f64 values (for `--f64` outputs); f32 otherwise, which every
    /// other encoding reads exactly as it would the f64 (scaled steps are 2^-12 of the P99 or
    /// coarser, 4000 times an f32's precision), at half the work directory's bytes.
    pub wide: bool,
}

impl ColumnSet {
    /// The columns written, in record order.
    pub fn columns(&self) -> Vec<Column> {
        let u = &self.unit;
        let mut v = Vec::new();
        let mut push = |name: &'static str, description: String, value| {
            v.push(Column {
                name,
                description,
                value,
            })
        };
        let has = |g| self.choice.has(g);
        if has(Group::Normals) {
            for (i, name) in ["NormalX", "NormalY", "NormalZ"].into_iter().enumerate() {
                push(
                    name,
                    format!("unit normal {}", &name[6..].to_lowercase()),
                    Value::Normal(i),
                );
            }
        }
        if has(Group::H) {
            push("H", format!("mean curvature (1/{u})"), Value::H);
        }
        if has(Group::K) {
            push("K", format!("Gaussian curvature (1/{u}^2)"), Value::K);
        }
        if has(Group::K1) {
            push("k1", format!("min principal curvature (1/{u})"), Value::K1);
        }
        if has(Group::K2) {
            push("k2", format!("max principal curvature (1/{u})"), Value::K2);
        }
        if has(Group::Directions) {
            for (i, name) in ["d1x", "d1y", "d1z"].into_iter().enumerate() {
                push(
                    name,
                    format!("direction of k1 ({})", &name[2..]),
                    Value::D1(i),
                );
            }
            for (i, name) in ["d2x", "d2y", "d2z"].into_iter().enumerate() {
                push(
                    name,
                    format!("direction of k2 ({})", &name[2..]),
                    Value::D2(i),
                );
            }
        }
        for (i, c) in self.extra.iter().enumerate() {
            push(c.name, c.description.to_string(), Value::Extra(i));
        }
        if has(Group::Scale) {
            push(
                "ScaleK",
                "neighbours of the chosen scale".into(),
                Value::ScaleK,
            );
            push(
                "ScaleFlags",
                "1saturated 2larger 4nocriterion".into(),
                Value::ScaleFlags,
            );
        }
        if has(Group::Flags) {
            push(
                FLAGS_NAME,
                "1few 2nrm 4dgn 8bnd 16umb 32file".into(),
                Value::Flags,
            );
        }
        for t in self.terrain() {
            let (name, description) = t.column(u);
            push(name, description, Value::Terrain(t));
        }
        v
    }

    /// The terrain values written, in record order: those of the chosen terrain groups, then
    /// the flags when any is chosen.
    fn terrain(&self) -> impl Iterator<Item = TerrainValue> + '_ {
        let any = self.choice.has_terrain();
        TerrainValue::ALL
            .into_iter()
            .filter(move |t| t.group().map_or(any, |g| self.choice.has(g)))
    }

    /// The values a result file stores (as f64 or f32, the flag bytes after them: the
    /// curvature flags, then [`Value::is_flag_byte`] ones; a record puts the terrain numbers
    /// after the flag bytes, [`ResultLayout`]): those of the columns written, with k1 and k2
    /// both when either is written (the flip of `--orient propagate` makes each from the
    /// other). An iterator, so that no point allocates.
    fn stored(&self) -> impl Iterator<Item = Value> + '_ {
        let on = |g| self.choice.has(g);
        let principal = on(Group::K1) || on(Group::K2);
        let normals = if on(Group::Normals) { 3 } else { 0 };
        let directions = if on(Group::Directions) { 3 } else { 0 };
        (0..normals)
            .map(Value::Normal)
            .chain(on(Group::H).then_some(Value::H))
            .chain(on(Group::K).then_some(Value::K))
            .chain(principal.then_some(Value::K1))
            .chain(principal.then_some(Value::K2))
            .chain((0..directions).map(Value::D1))
            .chain((0..directions).map(Value::D2))
            .chain((0..self.extra.len().min(MAX_EXTRA)).map(Value::Extra))
            .chain(on(Group::Scale).then_some(Value::ScaleK))
            .chain(on(Group::Scale).then_some(Value::ScaleFlags))
            .chain(self.terrain().map(Value::Terrain))
    }

    /// Bytes per stored value: 8 for f64, 4 for f32 ([`ColumnSet::wide`]).
    fn value_size(&self) -> usize {
        if self.wide {
            8
        } else {
            4
        }
    }

    /// Bytes per point of a result file's columns ([`ResultLayout::size`]).
    pub fn result_size(&self) -> usize {
        self.layout().size()
    }

    /// Where the stored number `v` starts in a record ([`ResultLayout::offset`]).
    pub fn stored_offset(&self, v: Value) -> Option<usize> {
        self.layout().offset(v)
    }

    /// The order, width and places of the stored values, for decoding records
    /// ([`ResultLayout::decode`]): the numbers, then the flag bytes.
    pub fn layout(&self) -> ResultLayout {
        let mut values = [Value::H; MAX_STORED];
        let mut len = 0;
        let numbers = self.stored().filter(|v| !v.is_flag_byte());
        for (slot, v) in values.iter_mut().zip(numbers) {
            *slot = v;
            len += 1;
        }
        let numbers = len;
        let bytes = self.stored().filter(|v| v.is_flag_byte());
        for (slot, v) in values[numbers..].iter_mut().zip(bytes) {
            *slot = v;
            len += 1;
        }
        let lead = (values[..numbers].iter())
            .position(|v| matches!(v, Value::Terrain(_)))
            .unwrap_or(numbers);
        ResultLayout {
            values,
            numbers,
            len,
            width: self.value_size(),
            lead,
        }
    }
}

#[cfg(test)]
mod tests;
