//! How numbers and instants read on the pages.

use crate::domain::timestamp::Timestamp;

/// A number to `digits` significant digits: fixed notation between 1e-3 and
/// 1e5, scientific outside (`-6.82520e-4`); `—` for none.
pub fn sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let digits = digits.max(1);
    let magnitude = v.abs().log10().floor() as i32;
    if (-3..5).contains(&magnitude) {
        let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.*e}", digits - 1)
    }
}

/// How a column prints its numbers: one notation for every row, so that a
/// column never mixes `-9.77e-4` with `-0.00126`. Fixed when every nonzero
/// value of the column is within 1e-3 ≤ |v| < 1e5, scientific otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Notation {
    /// `-0.00126`.
    Fixed,
    /// `-1.26e-3`.
    Scientific,
}

impl Notation {
    /// The notation of a column holding `values`.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Notation {
        let fixed = values
            .into_iter()
            .filter(|v| v.is_finite() && *v != 0.0)
            .all(|v| (-3..5).contains(&(v.abs().log10().floor() as i32)));
        if fixed {
            Notation::Fixed
        } else {
            Notation::Scientific
        }
    }

    /// `v` to `digits` significant digits in this notation.
    pub fn sig(self, v: f64, digits: usize) -> String {
        if !v.is_finite() {
            return "—".into();
        }
        if v == 0.0 {
            return "0".into();
        }
        let digits = digits.max(1);
        match self {
            Notation::Fixed => {
                let magnitude = v.abs().log10().floor() as i32;
                let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
                format!("{v:.decimals$}")
            }
            Notation::Scientific => format!("{v:.*e}", digits - 1),
        }
    }

    /// A coefficient in this notation (as [`num`]).
    pub fn num(self, v: f64) -> String {
        self.sig(v, 9)
    }

    /// An uncertainty in this notation (as [`unc`]).
    pub fn unc(self, v: f64) -> String {
        self.sig(v, 5)
    }
}

/// A value as it was given (a limit from a sensor type): the shortest text
/// that reads back as the same number (`-0.001`, not `-0.00100000000`).
pub fn given(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "—".into()
    }
}

/// A coefficient as the tables print it (9 significant digits, as the paper).
pub fn num(v: f64) -> String {
    sig(v, 9)
}

/// A standard error, dispersion or uncertainty (5 significant digits).
pub fn unc(v: f64) -> String {
    sig(v, 5)
}

/// The unit of a coefficient of `term` for outputs in `unit`: the output's
/// unit for `k0`, `unit/g` for the first-order terms, `unit/g²` for the
/// second-order ones, `unit/g³` for `kiii`.
pub fn term_unit(term: accelcal_core::Term, unit: &str) -> String {
    match term.degree() {
        0 => unit.to_owned(),
        1 => format!("{unit}/g"),
        2 => format!("{unit}/g²"),
        n => format!("{unit}/g{}", if n == 3 { "³" } else { "ⁿ" }),
    }
}

/// A value and its expanded uncertainty as a certificate states them
/// (GUM 7.2.6): the uncertainty to two significant digits, the value to the
/// same decimal place. Scientific notation shares one exponent, that of
/// the value (or of the uncertainty when the value is zero), when fixed
/// notation would need more than eight decimals.
pub fn value_and_uncertainty(value: f64, u: f64) -> (String, String) {
    if !value.is_finite() || !u.is_finite() || u <= 0.0 {
        return (num(value), unc(u));
    }
    // The place of the uncertainty's second significant digit.
    let place = u.abs().log10().floor() as i32 - 1;
    if place >= -8 {
        let decimals = (-place).max(0) as usize;
        return (format!("{value:.decimals$}"), format!("{u:.decimals$}"));
    }
    let reference = if value == 0.0 { u } else { value };
    let exponent = reference.abs().log10().floor() as i32;
    let decimals = (exponent - place).max(0) as usize;
    let scale = 10f64.powi(exponent);
    (
        format!("{:.decimals$}e{exponent}", value / scale),
        format!("{:.decimals$}e{exponent}", u / scale),
    )
}

/// An optional number.
pub fn opt(v: Option<f64>, f: fn(f64) -> String) -> String {
    v.map_or_else(|| "—".into(), f)
}

/// Effective degrees of freedom as a certificate prints them: the integer,
/// `∞` when infinite, `—` when the result did not state them.
pub fn dof(v: Option<Option<u64>>) -> String {
    match v {
        Some(Some(n)) => n.to_string(),
        Some(None) => "∞".into(),
        None => "—".into(),
    }
}

/// A coverage factor to two decimals, trailing zeros dropped (`2.87`, `2`,
/// `13.97`).
pub fn factor(k: f64) -> String {
    let s = format!("{k:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// A probability in per cent to two decimals (`95.45 %`).
pub fn percent(p: f64) -> String {
    format!("{:.2} %", p * 100.0)
}

/// An instant as `2026-11-22 08:00 UTC` (seconds when not zero).
pub fn instant(t: &Timestamp) -> String {
    let text = t.to_string();
    let (date, rest) = text.split_once('T').unwrap_or((&text, ""));
    let hms = rest.get(..8).unwrap_or("");
    let hm = if hms.ends_with(":00") {
        hms.get(..5).unwrap_or(hms)
    } else {
        hms
    };
    format!("{date} {hm} UTC")
}

/// The date of an instant, `2026-11-22`.
pub fn date(t: &Timestamp) -> String {
    let text = t.to_string();
    text.get(..10).unwrap_or(&text).to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values round to the place of their uncertainty's second significant
    /// digit; written out by hand.
    #[test]
    fn values_round_to_their_uncertainty() {
        assert_eq!(
            value_and_uncertainty(-1.216012345, 2.3287e-6),
            ("-1.2160123".into(), "0.0000023".into())
        );
        assert_eq!(
            value_and_uncertainty(6.2341e-3, 2.4424e-5),
            ("0.006234".into(), "0.000024".into())
        );
        assert_eq!(
            value_and_uncertainty(12.3456, 0.15),
            ("12.35".into(), "0.15".into())
        );
        assert_eq!(
            value_and_uncertainty(1234.4, 27.0),
            ("1234".into(), "27".into())
        );
        assert_eq!(
            value_and_uncertainty(-8.4e-10, 1.7e-11),
            ("-8.40e-10".into(), "0.17e-10".into())
        );
        assert_eq!(
            value_and_uncertainty(0.0, 1.7e-11),
            ("0.0e-11".into(), "1.7e-11".into())
        );
        assert_eq!(term_unit(accelcal_core::Term::K0, "mA"), "mA");
        assert_eq!(term_unit(accelcal_core::Term::Kp, "mA"), "mA/g");
        assert_eq!(term_unit(accelcal_core::Term::Kio, "mA"), "mA/g²");
        assert_eq!(term_unit(accelcal_core::Term::Kiii, "V"), "V/g³");
    }

    #[test]
    fn numbers_keep_their_significant_digits() {
        assert_eq!(num(-1.216154046322), "-1.21615405");
        assert_eq!(num(-0.000682520), "-6.82520000e-4");
        assert_eq!(unc(6.3637134e-6), "6.3637e-6");
        assert_eq!(sig(0.0062738449, 5), "0.0062738");
        assert_eq!(sig(12345.678, 3), "12346");
        assert_eq!(sig(123456.0, 3), "1.23e5");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(f64::NAN, 3), "—");
        assert_eq!(opt(None, num), "—");
    }

    /// Issue 31: a column keeps one notation, decided by all its values.
    #[test]
    fn a_column_keeps_one_notation() {
        let k0 = [-9.77e-4, -0.00126];
        let n = Notation::of(k0);
        assert_eq!(n, Notation::Scientific);
        assert_eq!(k0.map(|v| n.sig(v, 3)), ["-9.77e-4", "-1.26e-3"]);
        let ki = [-1.216154, -1.216198];
        let n = Notation::of(ki);
        assert_eq!(n, Notation::Fixed);
        assert_eq!(ki.map(|v| n.sig(v, 7)), ["-1.216154", "-1.216198"]);
        assert_eq!(Notation::of([0.0, f64::NAN, 2.5]), Notation::Fixed);
        assert_eq!(Notation::Fixed.sig(0.0, 3), "0");
        assert_eq!(given(-0.001), "-0.001");
        assert_eq!(given(-1.217), "-1.217");
    }

    #[test]
    fn instants_read_as_utc() {
        let t = Timestamp::parse("2026-11-22T08:00:00Z").unwrap();
        assert_eq!(instant(&t), "2026-11-22 08:00 UTC");
        let t = Timestamp::parse("2026-11-22T08:00:05.25Z").unwrap();
        assert_eq!(instant(&t), "2026-11-22 08:00:05 UTC");
        assert_eq!(date(&t), "2026-11-22");
    }
}
