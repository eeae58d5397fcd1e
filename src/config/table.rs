//! The rows of the option table ([`OPTIONS`]): every option that changes the output, with
//! its flag, default, help, text form and provenance line.

use std::fmt::Display;

use super::values::{KArg, OrientMode};
use super::{Choice, Length, OptionDef, ProvenanceLine};
use crate::core::estimate::EstimatorKind;
use crate::core::scale::Ladder;
use crate::core::select::{parse_classes, Classes};
use crate::io::columns::{ColumnChoice, ColumnType};

fn text<T: Display>(v: T) -> String {
    v.to_string()
}

fn opt_text<T: Display>(v: &Option<T>) -> String {
    v.as_ref().map(text).unwrap_or_default()
}

fn switch(v: &str) -> Result<bool, String> {
    v.parse::<bool>()
        .map_err(|_| format!("{v:?}: expected true or false"))
}

fn number<T: std::str::FromStr>(v: &str) -> Result<T, String> {
    v.trim()
        .parse::<T>()
        .map_err(|_| format!("{v:?} is not a whole number"))
}

/// `None` for the empty text (an option without a default, not given), else `parse(v)`.
fn optional<T>(v: &str, parse: impl Fn(&str) -> Result<T, String>) -> Result<Option<T>, String> {
    (!v.is_empty()).then(|| parse(v)).transpose()
}

/// The table. Its order is the provenance's order and the help's.
pub static OPTIONS: &[OptionDef] = &[
    OptionDef {
        key: "estimator",
        long: "estimator",
        short: None,
        aliases: &[],
        value_name: Some("NAME"),
        default: Some("cnc-avg-hexagram"),
        help: "Curvature estimator (docs/study.md compares their error and time per point).",
        choices: Some(|| {
            EstimatorKind::ALL
                .iter()
                .map(|e| Choice {
                    name: e.name(),
                    help: e.summary(),
                })
                .collect()
        }),
        set: |o, v| {
            o.estimator = EstimatorKind::from_name(v).ok_or_else(|| {
                let names: Vec<&str> = EstimatorKind::ALL.iter().map(|e| e.name()).collect();
                format!("{v:?}: unknown estimator; use one of {}", names.join(", "))
            })?;
            Ok(())
        },
        get: |o| text(o.estimator),
        provenance: Some(ProvenanceLine {
            key: "estimator",
            value: |p, _| Some(text(p.estimator)),
        }),
    },
    OptionDef {
        key: "k",
        long: "neighbours",
        short: Some('k'),
        aliases: &["neighbors"],
        value_name: Some("K|auto"),
        default: None,
        help: "Neighbours per point, the point itself included (as in the CNC authors' code). 30 \
suits aerial LIDAR (the CNC paper finds 15-50 very accurate on clean data; noisy scans want \
more). With --radius, the cap on neighbours: the nearest k within the radius (lidR's k with r, \
CloudCompare's and PDAL's radius with a maximum count); default 30, or 100 with --radius.\n\n\
`-k auto` chooses K per point among the rungs of --k-range (default 20..320) by the stability \
of H across scales (docs/scale.md): for noisy or unevenly noisy scans, where no single K suits \
every region. About 9-13x the CPU time of -k 30 (1.5x -k 320); writes the chosen K (ScaleK) \
and ScaleFlags (1: the top rung was chosen while the error was still falling).",
        choices: None,
        set: |o, v| {
            o.k = optional(v, KArg::parse)?;
            Ok(())
        },
        get: |o| opt_text(&o.k),
        provenance: Some(ProvenanceLine {
            key: "k",
            value: |p, _| Some(text(p.k)),
        }),
    },
    OptionDef {
        key: "k_range",
        long: "k-range",
        short: None,
        aliases: &[],
        value_name: Some("MIN..MAX"),
        default: None,
        help: "The ladder of -k auto: MIN..MAX, rungs MIN, 2 MIN, 4 MIN, ... up to MAX (MAX = MIN \
times 4 to 64, MIN at least 16). Implies -k auto.",
        choices: None,
        set: |o, v| {
            o.k_range = optional(v, Ladder::parse)?;
            Ok(())
        },
        get: |o| opt_text(&o.k_range),
        provenance: Some(ProvenanceLine {
            key: "k_range",
            value: |p, _| {
                Some(match p.ladder {
                    Some(l) => format!("{l} (-k auto: the scale chosen per point, ScaleK)"),
                    None => "none (one k)".into(),
                })
            },
        }),
    },
    OptionDef {
        key: "radius",
        long: "radius",
        short: None,
        aliases: &[],
        value_name: Some("LENGTH"),
        default: None,
        help: "Neighbourhoods by distance instead of count: each point with every point within \
this distance, at most -k of them (the nearest; default 100). A length with a unit like --tile: \
1.5m, 5ft, 5usft, or a bare number in file units, converted with the file's CRS unit (taken as \
file units, with a warning, when the file has none). Distances are 3D.\n\nUse it when the scale \
of the measure must not follow the density (curvature at a set scale across flight lines and \
overlaps); -k alone adapts to the density instead. Points with fewer than 3 neighbours within \
it are flagged FEW_NEIGHBOURS (flag 1).",
        choices: None,
        set: |o, v| {
            o.radius = optional(v, Length::parse)?;
            Ok(())
        },
        get: |o| opt_text(&o.radius),
        provenance: Some(ProvenanceLine {
            key: "radius",
            value: |p, r| {
                Some(match (p.radius, r.radius) {
                    (Some(given), Some(size)) => format!(
                        "{given} ({size} {}; at most k neighbours within it)",
                        r.unit_name
                    ),
                    _ => "none (k nearest neighbours)".into(),
                })
            },
        }),
    },
    OptionDef {
        key: "seed",
        long: "seed",
        short: None,
        aliases: &[],
        value_name: Some("SEED"),
        default: Some("0"),
        help: "Seed of randomised estimators (each point's stream comes from the seed and the \
point's coordinates, so that it does not depend on the order of the records).",
        choices: None,
        set: |o, v| {
            o.seed = number(v)?;
            Ok(())
        },
        get: |o| text(o.seed),
        provenance: Some(ProvenanceLine {
            key: "seed",
            value: |p, _| Some(text(p.estimator_params.seed)),
        }),
    },
    OptionDef {
        key: "triangles",
        long: "triangles",
        short: None,
        aliases: &[],
        value_name: Some("L"),
        default: Some("100"),
        help: "Triangles per point of --estimator cnc-uniform (at least 1; refused with another \
estimator, which does not use it). Recorded in the provenance with cnc-uniform.",
        choices: None,
        set: |o, v| {
            o.triangles = number(v)?;
            Ok(())
        },
        get: |o| text(o.triangles),
        provenance: Some(ProvenanceLine {
            key: "triangles",
            value: |p, _| {
                (p.estimator == EstimatorKind::CncUniform)
                    .then(|| text(p.estimator_params.triangles))
            },
        }),
    },
    OptionDef {
        key: "jet_degree",
        long: "jet-degree",
        short: None,
        aliases: &[],
        value_name: Some("2..4"),
        default: Some("2"),
        help: "Degree of the osculating jet of --estimator jet: 2 (a quadric, the least noise) to \
4 (needs at least 15 neighbours; follows higher-order shapes at small k). Refused with another \
estimator, which does not use it. Recorded in the provenance when it is not 2.",
        choices: None,
        set: |o, v| {
            o.jet_degree = number(v)?;
            Ok(())
        },
        get: |o| text(o.jet_degree),
        provenance: Some(ProvenanceLine {
            key: "jet_degree",
            value: |p, _| {
                let d = p.estimator_params.jet_degree;
                (d != 2).then(|| text(d))
            },
        }),
    },
    OptionDef {
        key: "ignore_file_normals",
        long: "ignore-file-normals",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Estimate normals by PCA even when the input has NormalX/Y/Z (a tilecurv output's \
own NormalX/Y/Z are never the file's normals: a re-run replaces them).",
        choices: None,
        set: |o, v| {
            o.ignore_file_normals = switch(v)?;
            Ok(())
        },
        get: |o| text(o.ignore_file_normals),
        provenance: Some(ProvenanceLine {
            key: "normals",
            value: |_, r| Some(if r.file_normals { "file" } else { "pca" }.into()),
        }),
    },
    OptionDef {
        key: "orient",
        long: "orient",
        short: None,
        aliases: &[],
        value_name: Some("RULE"),
        default: Some("up"),
        help: "Orientation of PCA normals: `up` (towards +Z, aerial scans), `outward` (away from \
the centroid of all points: closed, star-shaped objects), `propagate` (consistent over the \
neighbour graph, seeded outward: objects like the Stanford bunny; tile by tile, with the \
tiles' signs reconciled through their halos) or `viewpoint:X,Y,Z` (towards a terrestrial \
scanner, in file coordinates). Normals stored in the file (NormalX/Y/Z) are used as they are \
unless --ignore-file-normals.",
        choices: None,
        set: |o, v| {
            o.orient = OrientMode::parse(v)?;
            Ok(())
        },
        get: |o| text(o.orient),
        provenance: Some(ProvenanceLine {
            key: "orientation",
            value: |p, _| Some(text(p.orientation)),
        }),
    },
    OptionDef {
        key: "tile",
        long: "tile",
        short: None,
        aliases: &[],
        value_name: Some("LENGTH"),
        default: Some("50m"),
        help: "Tile edge length, with a unit: 50m, 0.1km, 150ft (international foot), 150usft (US \
survey foot), or a bare number in file units. Converted with the file's CRS unit (e.g. 50m is \
164.04 in a file in international feet). Results do not depend on it; it trades memory for \
halo overhead.",
        choices: None,
        set: |o, v| {
            o.tile = Length::parse(v)?;
            Ok(())
        },
        get: |o| text(o.tile),
        provenance: Some(ProvenanceLine {
            key: "tile",
            value: |p, r| Some(format!("{} ({} {})", p.tile, r.tile_size, r.unit_name)),
        }),
    },
    OptionDef {
        key: "columns",
        long: "columns",
        short: None,
        aliases: &[],
        value_name: Some("LIST"),
        default: Some("H,K,flags"),
        help: "The new columns, a comma-separated list of: normals (NormalX/Y/Z), H, K, k1, k2, \
directions (d1x..d2z), features (with --estimator vcm: SharpFeature, VcmNormalX/Y/Z), scale \
(ScaleK, ScaleFlags: the K -k auto chose; always written with -k auto), flags \
(CurvatureFlags), then the terrain columns (gravity along -z of the file, convex positive; docs/algorithms.md 10): profile (ProfileCurvature, 1/unit), tangential (TangentialCurvature), plan (PlanCurvature), shape_index (ShapeIndex, -1 bowl .. +1 dome), curvedness (Curvedness), slope (Slope, degrees), aspect (Aspect, downslope, degrees clockwise from north), or terrain for all seven; TerrainFlags comes with any of them, saying why a value is undefined (1: slope under 0.1 degree: profile, tangential, plan and aspect; 2: the curvature is undefined: all but slope and aspect; 4: a plane, k1 = k2 = 0: the shape index; 8: no normal: slope and aspect). Written in that order whatever the order given.\n\nThe default, H,K,flags, \
keeps a LAZ output within 2x its LAZ input on aerial and forest LIDAR; the normals and k1 with \
k2 cost about as much again each (`--columns normals,H,K,k1,k2,flags`: 3 to 4.2 times the \
input). Normals already in the input are kept and not written again.",
        choices: None,
        set: |o, v| {
            o.columns = ColumnChoice::parse(v)?;
            Ok(())
        },
        get: |o| text(o.columns),
        provenance: Some(ProvenanceLine {
            key: "columns",
            value: |p, _| Some(text(p.columns)),
        }),
    },
    OptionDef {
        key: "directions",
        long: "directions",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Also write the principal directions d1 (of k1) and d2 (of k2) as unit vectors (the \
column group `directions`).",
        choices: None,
        set: |o, v| {
            o.directions = switch(v)?;
            Ok(())
        },
        get: |o| text(o.directions),
        provenance: None,
    },
    OptionDef {
        key: "features",
        long: "features",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Also write the VCM's sharp-feature columns (only with --estimator vcm): \
SharpFeature, the score lambda2/(lambda1+lambda2+lambda3) of the convolved Voronoi covariance \
measure (eigenvalues in decreasing order), and VcmNormalX/Y/Z, the VCM's own unit normal \
(signed to agree with the PCA or file normal).\n\nThe score lies in [0, 1/2]: about 0 on a plane \
or smooth surface, about alpha^2/12 on a sharp edge of external (dihedral turning) angle alpha \
in radians (about 0.2-0.3 on a right-angled edge), and around 0.2 at a corner; threshold it to \
select creases. The column group `features`.",
        choices: None,
        set: |o, v| {
            o.features = switch(v)?;
            Ok(())
        },
        get: |o| text(o.features),
        provenance: None,
    },
    OptionDef {
        key: "f32",
        long: "f32",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Store the new columns of a LAS/LAZ output as 32-bit floats (NaN where undefined). \
By default they are scaled integers, which readers turn back into numbers with the extra-bytes \
descriptors' scale (laspy and PDAL apply it) and which LAZ compresses far better (with \
--columns normals,H,K,k1,k2,flags a LAZ output of forest LIDAR is about 4 times its LAZ input \
instead of 6.5).\n\nUnit vectors (normals, directions, the VCM normal) are stored as i16 at \
1/32767 (error at most 1.5e-5); H, K, and k1 with k2, as i32 at a power-of-two step of at most \
1/4096 of the 99th percentile of |value| over all the points of the run (error at most 1.2e-4 \
of that percentile; the RMS quantisation error is 27 to 160 times below the estimator's RMS \
error on the CNC authors' torus, 570 to 830 times on generated terrain), coarser only if the \
largest |value| would exceed 2^30 steps. `tilecurv info` prints each column's step. An \
undefined value is the type's minimum (-32768 or -2147483648), declared as the column's \
no-data value: laspy returns it scaled, so mask it with CurvatureFlags & 7 (or the raw value). \
PLY has no scale field: PLY outputs are f32 unless --f64.",
        choices: None,
        set: |o, v| {
            o.f32 = switch(v)?;
            Ok(())
        },
        get: |o| text(o.f32),
        provenance: Some(ProvenanceLine {
            key: "encoding",
            value: |p, _| {
                Some(
                    match p.column_type {
                        ColumnType::Scaled => "scaled (LAS/LAZ; f32 in PLY), column.* lines below",
                        ColumnType::F32 => "f32",
                        ColumnType::F64 => "f64",
                    }
                    .into(),
                )
            },
        }),
    },
    OptionDef {
        key: "f64",
        long: "f64",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Store the new columns as 64-bit floats (NaN where undefined) instead of scaled \
integers.",
        choices: None,
        set: |o, v| {
            o.f64 = switch(v)?;
            Ok(())
        },
        get: |o| text(o.f64),
        provenance: None,
    },
    OptionDef {
        key: "keep_version",
        long: "keep-version",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Write a LAS/LAZ output in its input's LAS version. By default a LAS 1.0-1.3 input \
gives a LAS 1.4 output (same point format and records; a 375-byte header with the 64-bit \
counts), because PDAL reads the extra-bytes columns of LAS 1.4 files only (without \
--readers.las.use_eb_vlr=true it shows none of the new columns in a LAS 1.2 file).",
        choices: None,
        set: |o, v| {
            o.keep_version = switch(v)?;
            Ok(())
        },
        get: |o| text(o.keep_version),
        provenance: Some(ProvenanceLine {
            key: "keep_version",
            value: |p, _| Some(text(p.keep_version)),
        }),
    },
    OptionDef {
        key: "ply_las_names",
        long: "ply-las-names",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Name the new columns of a PLY output as in LAS (NormalX/Y/Z, H, K, k1, k2, \
CurvatureFlags). By default they are nx/ny/nz and scalar_H, scalar_K, ...: the names \
CloudCompare loads as normals and scalar fields without a dialog (its command line ignores \
other names) and shows without the scalar_ prefix.",
        choices: None,
        set: |o, v| {
            o.ply_las_names = switch(v)?;
            Ok(())
        },
        get: |o| text(o.ply_las_names),
        provenance: Some(ProvenanceLine {
            key: "ply_las_names",
            value: |p, _| Some(text(p.ply_las_names)),
        }),
    },
    OptionDef {
        key: "classes",
        long: "classes",
        short: None,
        aliases: &[],
        value_name: Some("LIST"),
        default: None,
        help: "Compute only on points of these LAS classes, e.g. 2,9 (ground and water). \
Neighbourhoods are formed among the selected points only; every point stays in the output, the \
others with NaN values and flag 128 (not computed). Inputs without classes (PLY, XYZ, ...) \
cannot be filtered. Default: every class but --skip-classes",
        choices: None,
        set: |o, v| {
            o.classes = optional(v, parse_classes)?;
            Ok(())
        },
        get: |o| {
            o.classes
                .as_deref()
                .map(|c| text(Classes(c)))
                .unwrap_or_default()
        },
        provenance: Some(ProvenanceLine {
            key: "classes",
            value: |p, _| Some(p.select.only_text("all")),
        }),
    },
    OptionDef {
        key: "skip_classes",
        long: "skip-classes",
        short: None,
        aliases: &[],
        value_name: Some("LIST"),
        default: Some("7,18"),
        help: "Never compute on points of these LAS classes (they are written with flag 128). The \
default skips the noise classes, 7 (low point) and 18 (high noise), whose isolated points \
would bend their neighbours' curvature; `none` computes on every class",
        choices: None,
        set: |o, v| {
            o.skip_classes = parse_classes(v)?;
            Ok(())
        },
        get: |o| text(Classes(&o.skip_classes)),
        provenance: Some(ProvenanceLine {
            key: "skip_classes",
            value: |p, _| Some(text(Classes(&p.select.skip))),
        }),
    },
    OptionDef {
        key: "skip_withheld",
        long: "skip-withheld",
        short: None,
        aliases: &[],
        value_name: None,
        default: None,
        help: "Never compute on points with the LAS withheld flag (written with flag 128)",
        choices: None,
        set: |o, v| {
            o.skip_withheld = switch(v)?;
            Ok(())
        },
        get: |o| text(o.skip_withheld),
        provenance: Some(ProvenanceLine {
            key: "skip_withheld",
            value: |p, _| Some(text(p.select.skip_withheld)),
        }),
    },
    OptionDef {
        key: "sample_faces",
        long: "sample-faces",
        short: None,
        aliases: &[],
        value_name: Some("N"),
        default: None,
        help: "For a mesh (OBJ, OFF, or PLY with a face element): process N points sampled \
uniformly by area on its faces instead of its vertices, each with the unit normal of its face \
(polygons are fan-triangulated; counter-clockwise vertex order is outward), used as a file \
normal. N as for `generate --points`: 200k, 1M. The sample comes from --seed and does not \
depend on --threads or --chunk-size. The mesh is held in memory, the samples are streamed.",
        choices: None,
        set: |o, v| {
            o.sample_faces = optional(v, super::parse_count)?;
            Ok(())
        },
        get: |o| opt_text(&o.sample_faces),
        provenance: Some(ProvenanceLine {
            key: "sample_faces",
            value: |p, _| {
                p.sample_faces
                    .map(|n| format!("{n} (points sampled on the mesh faces)"))
            },
        }),
    },
];
