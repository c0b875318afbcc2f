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

/// The canonical form, `YYYY-MM-DDTHH:MM:SS.ffffffZ`.
const CANONICAL: &[time::format_description::BorrowedFormatItem<'static>] =
    format_description!("[year]-[month]-[day]T[hour]:[minute]:[second].[subsecond digits:6]Z");

impl Timestamp {
    /// The canonical text.
    fn text(&self) -> Result<String, time::error::Format> {
        self.0.format(&CANONICAL)
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text().map_err(|_| fmt::Error)?)
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
        let text = self
            .text()
            .map_err(|_| serde::ser::Error::custom("a timestamp did not format"))?;
        s.serialize_str(&text)
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

    /// Every year 0000–9999 is four digits; outside them (a date-time a
    /// database might hand back, which no input parses to) the text is
    /// still `time`'s and serialises as that string.
    #[test]
    fn extreme_years_keep_the_form() {
        for (given, text) in [
            ("0000-01-01T00:00:00Z", "0000-01-01T00:00:00.000000Z"),
            (
                "9999-12-31T23:59:59.9999999Z",
                "9999-12-31T23:59:59.999999Z",
            ),
            ("1970-01-01T00:00:00.000001Z", "1970-01-01T00:00:00.000001Z"),
        ] {
            let t = Timestamp::parse(given).unwrap();
            assert_eq!(t.to_string(), text);
            assert_eq!(serde_json::to_string(&t).unwrap(), format!("\"{text}\""));
        }
        let t = Timestamp::from_datetime(time::macros::datetime!(-0001-06-01 12:00 UTC));
        assert_eq!(t.to_string(), "-0001-06-01T12:00:00.000000Z");
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
