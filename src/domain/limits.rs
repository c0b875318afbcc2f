//! The limits the API promises (see README "Limits" and `openapi.yaml`, which
//! is generated from these constants).

use std::ops::RangeInclusive;

/// Longest identifier (`sensor_id`, `station_id`, `sensor_type`), in characters.
pub const MAX_ID_CHARS: usize = 64;
/// Longest `unit`.
pub const MAX_UNIT_CHARS: usize = 32;
/// Longest position or token label.
pub const MAX_LABEL_CHARS: usize = 64;
/// Longest description, and longest name of an issuing laboratory.
pub const MAX_DESCRIPTION_CHARS: usize = 256;
/// Longest name of a token's holder (the person behind it).
pub const MAX_HOLDER_CHARS: usize = 128;
/// Longest `notes`.
pub const MAX_NOTES_CHARS: usize = 4096;
/// Most positions in one tumble.
pub const MAX_POSITIONS: usize = 360;
/// Most runs in one submission.
pub const MAX_RUNS: usize = 1000;
/// Most samples at one position of one run: a static window of 1 000 s at
/// 100 Hz.
pub const MAX_SAMPLES: usize = 100_000;
/// Most samples in one submission, over all runs and positions (16 MB of
/// `f64` once read; see [`DEFAULT_MAX_BODY_BYTES`]).
pub const MAX_TOTAL_SAMPLES: usize = 2_000_000;
/// Largest `count` of a summary reading (samples averaged on board, never
/// sent, so not counted against [`MAX_TOTAL_SAMPLES`]); below 2⁵³, so every
/// count is exact as an `f64`.
pub const MAX_SUMMARY_COUNT: u64 = 1_000_000_000;
/// Largest request body by default, after decompression
/// (`--max-body-bytes`): the largest submission, 2 000 000 samples, as JSON
/// or CSV at up to 32 bytes a sample (`-1.2345678901234567e-05,` and the
/// structure around it).
pub const DEFAULT_MAX_BODY_BYTES: usize = 64 * 1024 * 1024;
/// Bytes of request bodies held at once by default (`--body-budget-bytes`):
/// four largest bodies, of which one token may hold a quarter — one largest
/// body — at once.
pub const DEFAULT_BODY_BUDGET_BYTES: usize = 256 * 1024 * 1024;
/// Most fusion batches.
pub const MAX_BATCHES: u64 = 100;
/// Fusion batches when a request names none (the paper's two batches).
pub const DEFAULT_BATCHES: u64 = 2;
/// Largest magnitude of a reading (and of a value given to `/v1/fuse`), in
/// the output's unit.
pub const MAX_READING: f64 = 1e9;
/// Largest magnitude of a dividing-head angle, in degrees.
pub const MAX_ANGLE_DEG: f64 = 3600.0;
/// Largest magnitude of one explicit gravity component, in g.
pub const MAX_GRAVITY_COMPONENT: f64 = 10.0;
/// Accepted norm of explicit gravity components: a tumble in the 1 g field.
pub const GRAVITY_NORM: RangeInclusive<f64> = 0.9..=1.1;
/// How far ahead of the server's clock `performed_at` may lie, in seconds:
/// the skew of a station's clock that is forgiven (NTP keeps clocks within
/// milliseconds; five minutes covers a station that missed its sync for
/// days). A forgiven time is recorded as the time the submission was
/// received, so no calibration can be dated after its arrival and outrank,
/// as a sensor's latest, one that arrives after it. It may not lie before
/// 1970 either.
pub const MAX_FUTURE_SECONDS: i64 = 5 * 60;
/// Largest indexing error a stand may declare (1σ), in arcseconds.
pub const MAX_ANGLE_STD_ARCSEC: f64 = 3600.0;
/// Largest relative uncertainty of gravity a stand may declare.
pub const MAX_GRAVITY_REL_STD: f64 = 0.1;
/// Local gravity values a standard may give, in m/s² (the Earth's surface
/// spans about 9.76 to 9.84).
pub const GRAVITY_M_S2: RangeInclusive<f64> = 9.7..=9.9;
/// Largest uncertainty a thermometer may declare (1σ), in °C.
pub const MAX_TEMPERATURE_STD_C: f64 = 10.0;
/// Run temperatures accepted, in °C.
pub const TEMPERATURE_C: RangeInclusive<f64> = -100.0..=200.0;
/// Most outputs compensated in one request.
pub const MAX_OUTPUTS: usize = 10_000;
/// Largest magnitude of a known `a_p` or `a_o` given to compensation, in g.
pub const MAX_CROSS_G: f64 = 100.0;
/// Field errors listed in one answer; the rest are counted, not listed.
pub const MAX_LISTED_ERRORS: usize = 100;
/// Characters of client input an error message may echo.
pub const MAX_ECHO_CHARS: usize = 64;
/// Default page size of lists.
pub const DEFAULT_PAGE: usize = 50;
/// Largest page size of lists.
pub const MAX_PAGE: usize = 500;

/// Longest comment or reason, in characters.
pub const MAX_COMMENT_CHARS: usize = 2000;
/// The most degrees of freedom a certificate may state (beyond, leave them
/// out: infinite).
pub const MAX_DEGREES_OF_FREEDOM: f64 = 1_000_000.0;
/// Smallest coverage probability accepted.
pub const MIN_COVERAGE_PROBABILITY: f64 = 0.5;
/// Largest coverage probability accepted.
pub const MAX_COVERAGE_PROBABILITY: f64 = 0.9999;
/// Smallest coverage factor accepted: below 1 an "expanded" uncertainty
/// would be smaller than the standard one.
pub const MIN_COVERAGE_FACTOR: f64 = 1.0;
/// Largest coverage factor accepted.
pub const MAX_COVERAGE_FACTOR: f64 = 10.0;
/// Longest calibration interval accepted, in days (ten years).
pub const MAX_INTERVAL_DAYS: u32 = 3650;
