//! A triad's calibration in the forms firmware loads (issue 30, item 5):
//! `json`, `c`, `px4`, `ardupilot`.
//!
//! The convention everywhere: outputs `u` in the triad's unit, specific
//! force `g` in g, `u = b + S g`, compensation `g = T (u − b)` with
//! `T = S⁻¹`, matrices by rows (row `m` is axis `m`, `x, y, z`).
//!
//! **PX4** (`CAL_ACC0_{X,Y,Z}OFF`, `CAL_ACC0_{X,Y,Z}SCALE`, QGroundControl's
//! parameter-file lines `1 1 NAME VALUE 9`) and **ArduPilot**
//! (`INS_ACCOFFS_{X,Y,Z}`, `INS_ACCSCAL_{X,Y,Z}`, `NAME,VALUE` lines) both
//! correct `a = (u − offset) ⊙ scale` in m/s² with a *diagonal* scale: they
//! carry `b` (as m/s²) and `T`'s diagonal (times 9.80665 m/s², the
//! standard g both firmwares use), not `T`'s off-diagonal terms. The
//! export says so in the file's comments with the largest term dropped
//! (in g per g), and **refuses** when that term exceeds
//! [`MAX_DROPPED`] — dropping it would misread the specific force by more
//! than 1 % — pointing at `json` or `c`, which carry the whole matrix. Both
//! need outputs in m/s² or g; other units are refused.
//!
//! **Free text carries no code.** What a station or an admin wrote (the
//! unit, the sensor id in the source line) reaches a file only where the
//! format quotes it: in the C header as the string literals
//! `ACCELCAL_UNIT` and `ACCELCAL_SOURCE`, every byte outside printable
//! ASCII and every `"`, `\` and `?` (trigraphs) written as a three-digit
//! octal escape ([`c_string`]), never in a comment; in the parameter files
//! in `#` comment lines, printable ASCII only, anything else as `\u{…}`
//! ([`ascii_escaped`]), so no line break ever ends the comment; in JSON by
//! serde's own escaping.

use std::fmt::Write as _;

use super::triad::{COMPENSATION, COMPENSATION_SECOND_ORDER, MODEL, MODEL_SECOND_ORDER};

/// The largest off-diagonal term of `T` (relative to its diagonal) a
/// diagonal-only format may drop.
pub const MAX_DROPPED: f64 = 0.01;

/// Standard gravity, m/s², as PX4 and ArduPilot use it.
pub const STANDARD_G: f64 = 9.80665;

/// An export format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// JSON with the convention spelled out.
    Json,
    /// A C header.
    C,
    /// A PX4 parameter file.
    Px4,
    /// An ArduPilot parameter file.
    ArduPilot,
}

impl Format {
    /// Parses `json`, `c`, `px4` or `ardupilot`.
    pub fn parse(s: &str) -> Option<Format> {
        match s {
            "json" => Some(Format::Json),
            "c" => Some(Format::C),
            "px4" => Some(Format::Px4),
            "ardupilot" => Some(Format::ArduPilot),
            _ => None,
        }
    }

    /// The media type answered.
    pub fn media_type(self) -> &'static str {
        match self {
            Format::Json => "application/json",
            Format::C => "text/x-c; charset=utf-8",
            Format::Px4 | Format::ArduPilot => "text/plain; charset=utf-8",
        }
    }

    /// The file name suggested.
    pub fn file_name(self) -> &'static str {
        match self {
            Format::Json => "accelcal-triad.json",
            Format::C => "accelcal_triad.h",
            Format::Px4 => "accelcal-px4.params",
            Format::ArduPilot => "accelcal-ardupilot.param",
        }
    }
}

/// What is exported: `b`, `S`, `T` in a unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported<'a> {
    /// The outputs' unit.
    pub unit: &'a str,
    /// `b`.
    pub b: [f64; 3],
    /// `S`.
    pub s: [[f64; 3]; 3],
    /// `T = S⁻¹`.
    pub t: [[f64; 3]; 3],
    /// Each axis's second-order coefficient, when the model has them.
    pub s2: Option<[f64; 3]>,
    /// What the export describes (a calibration id, a sensor).
    pub source: String,
}

/// Why a format cannot carry a calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExportError {
    /// The outputs are not in m/s² or g.
    #[error(
        "{format} parameters are in m/s²: this triad's outputs are in `{unit}`; export `json` or `c`"
    )]
    Unit {
        /// The format.
        format: &'static str,
        /// The unit.
        unit: String,
    },
    /// Second-order terms, which the diagonal formats cannot carry.
    #[error(
        "{format} carries offsets and a diagonal scale only: this triad's model has second-order \
         terms (S2 = {s2:?}), which it would drop; export `json` or `c`, which carry them"
    )]
    SecondOrder {
        /// The format.
        format: &'static str,
        /// The terms.
        s2: [f64; 3],
    },
    /// An off-diagonal term too large to drop.
    #[error(
        "{format} carries a diagonal scale only: T's off-diagonal term {term} is {value:.3e} of its row's diagonal, \
         more than {MAX_DROPPED} (dropping it would misread the specific force by over 1 %); \
         export `json` or `c`, which carry the whole matrix"
    )]
    OffDiagonal {
        /// The format.
        format: &'static str,
        /// Which term (`T_xy`).
        term: String,
        /// Its size relative to the diagonal.
        value: f64,
    },
}

/// m/s² per unit of the outputs: 1 for `m/s2`, standard g for `g`.
pub fn to_m_s2(unit: &str) -> Option<f64> {
    match unit.trim() {
        "m/s2" | "m/s^2" | "m/s²" | "m s-2" => Some(1.0),
        "g" | "g0" | "gn" => Some(STANDARD_G),
        _ => None,
    }
}

/// `T`'s largest off-diagonal term relative to its row's diagonal, and
/// which (`T_xy`: row x, column y).
pub fn largest_off_diagonal(t: &[[f64; 3]; 3]) -> (String, f64) {
    const N: [&str; 3] = ["x", "y", "z"];
    let mut worst = (String::from("none"), 0.0);
    for r in 0..3 {
        for c in 0..3 {
            if r != c {
                let v = (t[r][c] / t[r][r]).abs();
                if v > worst.1 || v.is_nan() {
                    worst = (format!("T_{}{}", N[r], N[c]), v);
                }
            }
        }
    }
    worst
}

/// The export of `e` in `format`.
pub fn export(e: &Exported<'_>, format: Format) -> Result<String, ExportError> {
    match format {
        Format::Json => Ok(json(e)),
        Format::C => Ok(c_header(e)),
        Format::Px4 => diagonal(e, "PX4", |out, name, value| {
            let _ = writeln!(out, "1\t1\t{name}\t{value:.9}\t9");
        }),
        Format::ArduPilot => diagonal(e, "ArduPilot", |out, name, value| {
            let _ = writeln!(out, "{name},{value:.9}");
        }),
    }
}

fn json(e: &Exported<'_>) -> String {
    let (model, compensation) = match e.s2 {
        None => (MODEL, COMPENSATION),
        Some(_) => (MODEL_SECOND_ORDER, COMPENSATION_SECOND_ORDER),
    };
    let mut v = serde_json::json!({
        "source": e.source,
        "model": model,
        "compensation": compensation,
        "convention": "u: outputs in `unit`; g: specific force in g in the sensor's body frame; \
                       matrices by rows, row m = axis m (x, y, z)",
        "unit": e.unit,
        "units": {
            "b": e.unit,
            "S": format!("{}/g", e.unit),
            "T": format!("g/{}", e.unit),
        },
        "b": e.b,
        "S": e.s,
        "T": e.t,
    });
    if let Some(s2) = e.s2 {
        v["S2"] = serde_json::json!(s2);
        v["units"]["S2"] = serde_json::json!(format!("{}/g^2", e.unit));
    }
    let mut text = serde_json::to_string_pretty(&v).unwrap_or_default();
    text.push('\n');
    text
}

/// The symbols the C header defines, in order (besides its include guard
/// `ACCELCAL_TRIAD_H`); `ACCELCAL_S2` only for a second-order model.
pub const C_SYMBOLS: [&str; 6] = [
    "ACCELCAL_SOURCE",
    "ACCELCAL_UNIT",
    "ACCELCAL_B",
    "ACCELCAL_S",
    "ACCELCAL_T",
    "ACCELCAL_S2",
];

/// `s` as the inside of a C string literal: printable ASCII but `"`, `\`
/// and `?` as itself, every other byte of its UTF-8 as a three-digit octal
/// escape (octal, unlike `\x`, stops after three digits, and `?` escaped
/// keeps `??/` from being a trigraph).
pub fn c_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if (0x20..0x7f).contains(&b) && !matches!(b, b'"' | b'\\' | b'?') {
            out.push(char::from(b));
        } else {
            let _ = write!(out, "\\{b:03o}");
        }
    }
    out
}

/// `s` in printable ASCII for a comment line: `\` doubled, every other
/// character outside printable ASCII (line breaks included) as `\u{hex}`.
pub fn ascii_escaped(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            ' '..='~' => out.push(c),
            _ => {
                let _ = write!(out, "\\u{{{:x}}}", u32::from(c));
            }
        }
    }
    out
}

fn c_header(e: &Exported<'_>) -> String {
    let row = |r: &[f64; 3]| format!("{{ {:.12e}, {:.12e}, {:.12e} }}", r[0], r[1], r[2]);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "/* accelcal triad calibration (ACCELCAL_SOURCE says which). */"
    );
    let _ = writeln!(out, "/*");
    let _ = writeln!(
        out,
        " * Outputs u in ACCELCAL_UNIT (x, y, z); specific force g in g, body frame."
    );
    let _ = writeln!(out, " *   u = b + S g            (the model)");
    let _ = writeln!(out, " *   g = T (u - b)          (compensation, T = S^-1)");
    let _ = writeln!(
        out,
        " * i.e. g[m] = sum over k of ACCELCAL_T[m][k] * (u[k] - ACCELCAL_B[k])."
    );
    let _ = writeln!(out, " * Matrices by rows: row m is axis m.");
    if e.s2.is_some() {
        let _ = writeln!(
            out,
            " * Second order: u[m] = b[m] + (S g)[m] + ACCELCAL_S2[m] * g[m]^2; compensate by"
        );
        let _ = writeln!(
            out,
            " * Newton's iteration on g from g = T (u - b), Jacobian S + diag(2 * ACCELCAL_S2 * g)."
        );
    }
    let _ = writeln!(out, " */");
    let _ = writeln!(out, "#ifndef ACCELCAL_TRIAD_H");
    let _ = writeln!(out, "#define ACCELCAL_TRIAD_H");
    let _ = writeln!(
        out,
        "static const char ACCELCAL_SOURCE[] = \"{}\";",
        c_string(&e.source)
    );
    let _ = writeln!(
        out,
        "static const char ACCELCAL_UNIT[] = \"{}\";",
        c_string(e.unit)
    );
    let _ = writeln!(
        out,
        "static const double ACCELCAL_B[3] = {{ {:.12e}, {:.12e}, {:.12e} }};",
        e.b[0], e.b[1], e.b[2]
    );
    for (name, m) in [("S", &e.s), ("T", &e.t)] {
        let _ = writeln!(out, "static const double ACCELCAL_{name}[3][3] = {{");
        for (i, r) in m.iter().enumerate() {
            let _ = writeln!(out, "    {}{}", row(r), if i < 2 { "," } else { "" });
        }
        let _ = writeln!(out, "}};");
    }
    if let Some(s2) = e.s2 {
        let _ = writeln!(
            out,
            "static const double ACCELCAL_S2[3] = {{ {:.12e}, {:.12e}, {:.12e} }};",
            s2[0], s2[1], s2[2]
        );
    }
    let _ = writeln!(out, "#endif /* ACCELCAL_TRIAD_H */");
    out
}

/// PX4's and ArduPilot's offsets and diagonal scales.
fn diagonal(
    e: &Exported<'_>,
    format: &'static str,
    line: impl Fn(&mut String, &str, f64),
) -> Result<String, ExportError> {
    let per_unit = to_m_s2(e.unit).ok_or_else(|| ExportError::Unit {
        format,
        unit: e.unit.to_owned(),
    })?;
    if let Some(s2) = e.s2 {
        return Err(ExportError::SecondOrder { format, s2 });
    }
    let (term, value) = largest_off_diagonal(&e.t);
    if value.is_nan() || value > MAX_DROPPED {
        return Err(ExportError::OffDiagonal {
            format,
            term,
            value,
        });
    }
    // a = (u − offset) ⊙ scale in m/s²: offset = b in m/s², scale =
    // standard g · T_mm / (m/s² per unit).
    let offsets = e.b.map(|x| x * per_unit);
    let scales = [0, 1, 2].map(|m| STANDARD_G * e.t[m][m] / per_unit);
    let (off, scale): ([&str; 3], [&str; 3]) = if format == "PX4" {
        (
            ["CAL_ACC0_XOFF", "CAL_ACC0_YOFF", "CAL_ACC0_ZOFF"],
            ["CAL_ACC0_XSCALE", "CAL_ACC0_YSCALE", "CAL_ACC0_ZSCALE"],
        )
    } else {
        (
            ["INS_ACCOFFS_X", "INS_ACCOFFS_Y", "INS_ACCOFFS_Z"],
            ["INS_ACCSCAL_X", "INS_ACCSCAL_Y", "INS_ACCSCAL_Z"],
        )
    };
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# accelcal triad calibration for {format}: {}",
        ascii_escaped(&e.source)
    );
    let _ = writeln!(out, "# outputs u in {}", ascii_escaped(e.unit));
    let _ = writeln!(
        out,
        "# a = (u - offset) * scale, in m/s2, per axis; offsets = b, scales = {STANDARD_G} * diag(T)"
    );
    let _ = writeln!(
        out,
        "# NOT CARRIED: T's off-diagonal terms (misalignment), largest {term} = {value:.3e} of its row's diagonal"
    );
    if format == "PX4" {
        let _ = writeln!(
            out,
            "# Set CAL_ACC0_ID to the accelerometer's device id before loading."
        );
    }
    for m in 0..3 {
        line(&mut out, off[m], offsets[m]);
    }
    for m in 0..3 {
        line(&mut out, scale[m], scales[m]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triad(unit: &str, off: f64) -> Exported<'_> {
        // T lower-triangular with one off-diagonal term; S = T⁻¹ by hand.
        let t = [
            [1.0 / 9.8, 0.0, 0.0],
            [off / 9.8, 1.0 / 9.9, 0.0],
            [0.0, 0.0, 1.0 / 9.7],
        ];
        let s = [[9.8, 0.0, 0.0], [-off * 9.9, 9.9, 0.0], [0.0, 0.0, 9.7]];
        Exported {
            unit,
            b: [0.1, -0.2, 0.3],
            s,
            t,
            s2: None,
            source: "calibration X".into(),
        }
    }

    /// Second-order terms: json and c carry them and say how to compensate;
    /// the diagonal formats refuse rather than drop them.
    #[test]
    fn second_order_terms_go_to_json_and_c_only() {
        let e = Exported {
            s2: Some([1.5e-3, -2.5e-3, 0.0]),
            ..triad("m/s2", 0.0)
        };
        let v: serde_json::Value =
            serde_json::from_str(&export(&e, Format::Json).unwrap()).unwrap();
        assert_eq!(v["S2"], serde_json::json!([1.5e-3, -2.5e-3, 0.0]));
        assert_eq!(v["units"]["S2"], "m/s2/g^2");
        assert_eq!(v["model"], MODEL_SECOND_ORDER);
        let c = export(&e, Format::C).unwrap();
        assert!(
            c.contains(
                "ACCELCAL_S2[3] = { 1.500000000000e-3, -2.500000000000e-3, 0.000000000000e0 }"
            ),
            "{c}"
        );
        assert!(c.contains("Newton"));
        for f in [Format::Px4, Format::ArduPilot] {
            let err = export(&e, f).unwrap_err();
            assert!(matches!(err, ExportError::SecondOrder { .. }), "{err}");
            assert!(err.to_string().contains("json"));
        }
        let first: serde_json::Value =
            serde_json::from_str(&export(&triad("m/s2", 0.0), Format::Json).unwrap()).unwrap();
        assert!(first.get("S2").is_none());
        assert_eq!(first["model"], MODEL);
    }

    #[test]
    fn px4_and_ardupilot_carry_offsets_and_diagonal_scales() {
        let px4 = export(&triad("m/s2", 0.001), Format::Px4).unwrap();
        assert!(px4.contains("1\t1\tCAL_ACC0_XOFF\t0.100000000\t9"), "{px4}");
        assert!(px4.contains("1\t1\tCAL_ACC0_ZOFF\t0.300000000\t9"));
        // 9.80665 / 9.8 = 1.000678571…
        assert!(px4.contains("CAL_ACC0_XSCALE\t1.000678571\t9"), "{px4}");
        // T_yx / T_yy = (0.001 / 9.8) / (1 / 9.9) = 1.0102e-3.
        assert!(px4.contains("NOT CARRIED") && px4.contains("T_yx = 1.010e-3"));
        let ap = export(&triad("g", 0.001), Format::ArduPilot).unwrap();
        // In g: offsets × 9.80665, scales ÷ 9.80665.
        assert!(ap.contains("INS_ACCOFFS_Y,-1.961330000"), "{ap}");
        assert!(ap.contains(&format!("INS_ACCSCAL_Z,{:.9}", 1.0 / 9.7)));
    }

    #[test]
    fn what_a_format_cannot_carry_is_refused() {
        let e = export(&triad("m/s2", 0.02), Format::Px4).unwrap_err();
        assert!(matches!(e, ExportError::OffDiagonal { ref term, .. } if term == "T_yx"));
        assert!(e.to_string().contains("json"));
        let e = export(&triad("LSB", 0.0), Format::ArduPilot).unwrap_err();
        assert_eq!(
            e,
            ExportError::Unit {
                format: "ArduPilot",
                unit: "LSB".into()
            }
        );
        // json and c carry anything.
        assert!(export(&triad("LSB", 0.02), Format::Json).is_ok());
        assert!(export(&triad("LSB", 0.02), Format::C).is_ok());
    }

    #[test]
    fn json_and_c_carry_the_whole_matrix() {
        let e = triad("m/s2", 0.02);
        let v: serde_json::Value =
            serde_json::from_str(&export(&e, Format::Json).unwrap()).unwrap();
        assert_eq!(v["T"][1][0], e.t[1][0]);
        assert_eq!(v["S"][1][0], e.s[1][0]);
        assert_eq!(v["units"]["S"], "m/s2/g");
        let c = export(&e, Format::C).unwrap();
        assert!(c.contains("ACCELCAL_T[3][3]") && c.contains(&format!("{:.12e}", e.t[1][0])));
        assert!(c.contains("g = T (u - b)"));
    }

    #[test]
    fn formats_parse() {
        for (s, f) in [
            ("json", Format::Json),
            ("c", Format::C),
            ("px4", Format::Px4),
            ("ardupilot", Format::ArduPilot),
        ] {
            assert_eq!(Format::parse(s), Some(f));
        }
        assert_eq!(Format::parse("csv"), None);
    }
}
