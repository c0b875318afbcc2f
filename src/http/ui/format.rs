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

/// A coefficient as the tables print it (9 significant digits, as the paper).
pub fn num(v: f64) -> String {
    sig(v, 9)
}

/// A standard error, dispersion or uncertainty (5 significant digits).
pub fn unc(v: f64) -> String {
    sig(v, 5)
}

/// An optional number.
pub fn opt(v: Option<f64>, f: fn(f64) -> String) -> String {
    v.map_or_else(|| "—".into(), f)
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

    #[test]
    fn instants_read_as_utc() {
        let t = Timestamp::parse("2026-11-22T08:00:00Z").unwrap();
        assert_eq!(instant(&t), "2026-11-22 08:00 UTC");
        let t = Timestamp::parse("2026-11-22T08:00:05.25Z").unwrap();
        assert_eq!(instant(&t), "2026-11-22 08:00:05 UTC");
        assert_eq!(date(&t), "2026-11-22");
    }
}
