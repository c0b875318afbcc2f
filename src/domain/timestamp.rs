//! UTC timestamps in one canonical RFC 3339 form.
//!
//! Every instant accelcal stores or returns is UTC with exactly six fractional
//! digits, `2026-11-20T08:00:00.000000Z`: fixed width, so the text sorts in
//! time order in any database, and lossless for microsecond clocks. Inputs may
//! use any RFC 3339 offset and precision; they are converted to UTC and
//! truncated to the microsecond.

use std::fmt;

use serde::{Serialize, Serializer};
use time::format_description::well_known::Rfc3339;
use time::macros::format_description;
use time::{OffsetDateTime, UtcOffset};

/// An instant, UTC, microsecond resolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Timestamp(OffsetDateTime);

/// Why a timestamp string was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TimestampError {
    /// Not RFC 3339.
    #[error("must be an RFC 3339 date-time such as 2026-11-20T08:00:00Z")]
    Format,
}

impl Timestamp {
    /// The current time.
    pub fn now() -> Self {
        Self::from_datetime(OffsetDateTime::now_utc())
    }

    /// The instant `t`, truncated to the microsecond (how databases hand
    /// timestamps back).
    pub fn from_datetime(t: OffsetDateTime) -> Self {
        let t = t.to_offset(UtcOffset::UTC);
        let micros = t.microsecond();
        Timestamp(t.replace_microsecond(micros).expect("microsecond in range"))
    }

    /// Parses any RFC 3339 date-time whose UTC instant lies in years 0000–9999.
    pub fn parse(s: &str) -> Result<Self, TimestampError> {
        let t = OffsetDateTime::parse(s, &Rfc3339).map_err(|_| TimestampError::Format)?;
        let t = Self::from_datetime(t);
        if !(0..=9999).contains(&t.0.year()) {
            return Err(TimestampError::Format);
        }
        Ok(t)
    }

    /// As a `time` date-time, UTC (how databases take timestamps).
    pub fn datetime(&self) -> OffsetDateTime {
        self.0
    }

    /// The calendar year (UTC).
    pub fn year(&self) -> i32 {
        self.0.year()
    }

    /// Microseconds since the Unix epoch.
    pub fn unix_micros(&self) -> i64 {
        (self.0.unix_timestamp_nanos() / 1000) as i64
    }

    /// The instant `micros` microseconds after the Unix epoch, if it lies in
    /// years 0000–9999.
    pub fn from_unix_micros(micros: i64) -> Option<Self> {
        let t = OffsetDateTime::from_unix_timestamp_nanos(i128::from(micros) * 1000).ok()?;
        (0..=9999).contains(&t.year()).then_some(Timestamp(t))
    }

    /// This instant moved by `seconds`.
    pub fn plus_seconds(&self, seconds: i64) -> Self {
        Timestamp(self.0 + time::Duration::seconds(seconds))
    }
}

/// `v` in decimal, right-aligned and zero-padded, filling `out`.
fn digits(out: &mut [u8], mut v: u32) {
    for slot in out.iter_mut().rev() {
        *slot = b'0' + (v % 10) as u8;
        v /= 10;
    }
}

impl Timestamp {
    /// `time`'s rendering of the canonical form: the reference, and the
    /// answer for years outside 0000–9999 (which no input parses to).
    fn formatted(&self) -> Result<String, time::error::Format> {
        let format = format_description!(
            "[year]-[month]-[day]T[hour]:[minute]:[second].[subsecond digits:6]Z"
        );
        self.0.format(&format)
    }

    /// The canonical form `YYYY-MM-DDTHH:MM:SS.ffffffZ`, written digit by
    /// digit into 27 bytes (a history page writes dozens; `time`'s general
    /// formatter cost about 2 300 instructions each, BENCHMARKS.md), or
    /// `None` outside years 0000–9999.
    fn canonical(&self) -> Option<[u8; 27]> {
        let t = self.0;
        let year = u32::try_from(t.year()).ok().filter(|y| *y <= 9999)?;
        let mut b = *b"0000-00-00T00:00:00.000000Z";
        digits(&mut b[0..4], year);
        digits(&mut b[5..7], u32::from(u8::from(t.month())));
        digits(&mut b[8..10], u32::from(t.day()));
        digits(&mut b[11..13], u32::from(t.hour()));
        digits(&mut b[14..16], u32::from(t.minute()));
        digits(&mut b[17..19], u32::from(t.second()));
        digits(&mut b[20..26], t.microsecond());
        Some(b)
    }

    /// Calls `f` with the canonical text.
    fn with_text<R>(&self, f: impl FnOnce(&str) -> R) -> Result<R, fmt::Error> {
        match self.canonical() {
            // ASCII digits and separators only.
            Some(b) => Ok(f(std::str::from_utf8(&b).map_err(|_| fmt::Error)?)),
            None => Ok(f(&self.formatted().map_err(|_| fmt::Error)?)),
        }
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.with_text(|s| f.write_str(s))?
    }
}

impl utoipa::PartialSchema for Timestamp {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        utoipa::openapi::ObjectBuilder::new()
            .schema_type(utoipa::openapi::Type::String)
            .format(Some(utoipa::openapi::SchemaFormat::KnownFormat(
                utoipa::openapi::KnownFormat::DateTime,
            )))
            .into()
    }
}

impl utoipa::ToSchema for Timestamp {}

impl<'de> serde::Deserialize<'de> for Timestamp {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        Timestamp::parse(&s).map_err(serde::de::Error::custom)
    }
}

impl Serialize for Timestamp {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.with_text(|text| s.serialize_str(text))
            .map_err(|_| serde::ser::Error::custom("a timestamp did not format"))?
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unix_microseconds_round_trip() {
        let t = Timestamp::parse("2026-11-20T09:30:00.123456Z").unwrap();
        assert_eq!(Timestamp::from_unix_micros(t.unix_micros()), Some(t));
        assert_eq!(Timestamp::from_unix_micros(i64::MAX), None);
    }

    #[test]
    fn canonical_form_is_utc_fixed_width() {
        let t = Timestamp::parse("2026-11-20T09:30:00.1234567+01:30").unwrap();
        assert_eq!(t.to_string(), "2026-11-20T08:00:00.123456Z");
        assert_eq!(Timestamp::parse(&t.to_string()), Ok(t));
        let z = Timestamp::parse("2026-11-20T08:00:00Z").unwrap();
        assert_eq!(z.to_string(), "2026-11-20T08:00:00.000000Z");
    }

    /// The canonical form written digit by digit is `time`'s, for every
    /// instant of years 0000–9999 (and serialises as that string).
    #[test]
    fn canonical_text_is_times_format() {
        let first = Timestamp::parse("0000-01-01T00:00:00Z")
            .unwrap()
            .unix_micros();
        let last = Timestamp::parse("9999-12-31T23:59:59.999999Z")
            .unwrap()
            .unix_micros();
        let check = |micros: i64| {
            let t = Timestamp::from_unix_micros(micros).unwrap();
            let expected = t.formatted().unwrap();
            assert_eq!(t.to_string(), expected, "{micros}");
            assert_eq!(
                serde_json::to_string(&t).unwrap(),
                format!("\"{expected}\""),
                "{micros}"
            );
        };
        for micros in [
            first,
            last,
            0,
            -1,
            1,
            951_782_400_000_000,
            1_700_000_000_123_456,
        ] {
            check(micros);
        }
        let mut rng = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..20_000 {
            // xorshift: reproducible, spread over the whole range.
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let span = (last - first) as u64;
            check(first + (rng % span) as i64);
        }
    }

    /// Outside years 0000–9999 (a date-time a database might hand back; no
    /// input parses to one), the text is `time`'s own.
    #[test]
    fn outside_years_0000_to_9999_falls_back_to_time() {
        let t = Timestamp::from_datetime(time::macros::datetime!(-0001-06-01 12:00 UTC));
        assert_eq!(t.canonical(), None);
        assert_eq!(t.to_string(), "-0001-06-01T12:00:00.000000Z");
        assert_eq!(t.to_string(), t.formatted().unwrap());
    }

    #[test]
    fn refusals() {
        assert_eq!(Timestamp::parse("2026-11-20"), Err(TimestampError::Format));
        assert_eq!(Timestamp::parse("yesterday"), Err(TimestampError::Format));
        assert_eq!(
            Timestamp::parse("0000-01-01T00:30:00+01:00"),
            Err(TimestampError::Format)
        );
        assert_eq!(
            Timestamp::parse("0000-01-01T00:00:00Z")
                .unwrap()
                .to_string(),
            "0000-01-01T00:00:00.000000Z"
        );
    }
}
