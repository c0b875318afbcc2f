//! A triad submission's body as it arrives, and as checked: the three
//! forms (known orientations, static positions, a recording), the
//! standards and stand it names, and the detector's parameters.

use super::*;

/// Largest sampling rate, Hz.
pub(super) const MAX_RATE_HZ: f64 = 1e6;
/// Largest detector time, s.
pub(super) const MAX_DETECTOR_S: f64 = 3600.0;
/// Largest detector threshold multiple.
pub(super) const MAX_THRESHOLD: f64 = 1e6;
/// The detector's smallest settings: a still period and a shortest
/// interval of 0.5 s, a window of 0.1 s and of at least
/// [`MIN_WINDOW_SAMPLES`] samples, and a threshold of 2 — at a threshold near
/// 1 the still noise's own variance crosses it half the time, and one held
/// orientation falls apart into many short "intervals".
pub const MIN_DETECTOR: Detector = Detector {
    still_s: 0.5,
    window_s: 0.1,
    threshold: 2.0,
    min_static_s: 0.5,
};
/// Fewest samples in the detector's moving window.
pub const MIN_WINDOW_SAMPLES: f64 = 10.0;

/// The body of `POST /v1/identify/triad`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadBody {
    /// The triad's id: echoed by `POST /v1/identify/triad`, required to
    /// store it (`POST /v1/calibrations/triad`); letters, digits and
    /// `. _ : -`, at most 64 characters.
    #[serde(default)]
    pub sensor_id: Option<String>,
    /// The submitting station (stored; a station-bound token's own).
    #[serde(default)]
    pub station_id: Option<String>,
    /// When the test was performed, RFC 3339 (stored; default: when
    /// received).
    #[serde(default)]
    pub performed_at: Option<String>,
    /// The outputs' unit (default `output`): `m/s2` or `g` for the PX4 and
    /// ArduPilot exports.
    #[serde(default)]
    pub unit: Option<String>,
    /// Known orientations: specific force in the body frame, in g, per
    /// position (each of magnitude 1), or `six_faces` (+x, −x, +y, −y, +z,
    /// −z up) or `cube24` (the 24 orientations of a cube: each face up,
    /// turned four times about the vertical).
    #[serde(default)]
    pub orientations: Option<OrientationsBody>,
    /// With `orientations`: each run's samples per position.
    #[serde(default)]
    pub runs: Option<Vec<TriadRunBody>>,
    /// With `orientations`: batches for the fusion (default 1).
    #[serde(default)]
    pub batches: Option<usize>,
    /// Unknown orientations: each static position's samples of
    /// `(u_x, u_y, u_z)` (at least nine positions).
    #[serde(default)]
    pub static_positions: Option<Vec<Vec<[f64; 3]>>>,
    /// With `static_positions`: each position's temperature, °C (−100 to
    /// 200), one per position; `POST /v1/identify/thermal/triad` groups
    /// the positions into set points by it, a triad at one temperature
    /// takes their mean (all within 0.5 K) as its `temperature_c`.
    #[serde(default)]
    pub static_temperatures_c: Option<Vec<f64>>,
    /// Unknown orientations from one continuous recording.
    #[serde(default)]
    pub recording: Option<RecordingBody>,
    /// The uncertainty budget's stand: with `orientations`, the dividing
    /// head's indexing error and the local gravity's relative uncertainty
    /// (each default 0); without, only `gravity_rel_std` (the fit uses no
    /// orientation, so no indexing error enters it).
    #[serde(default)]
    pub stand: Option<TriadStandBody>,
    /// Stored triads: the sensor type whose limits judge the elements (the
    /// sensor's own by default; as for a single-axis submission).
    #[serde(default)]
    pub sensor_type: Option<String>,
    /// Reference standards from the registry, by id: the `stand` (its
    /// indexing error enters the budget instead of `stand`'s), the
    /// `thermometer` and the local `gravity` value; each must be in
    /// calibration when the test was performed. Stored triads and triad
    /// models only.
    #[serde(default)]
    pub standards: Option<TriadStandardsBody>,
    /// With `orientations`: give each axis its second-order term `kii`
    /// (`S2_m g_m²`); compensation then solves the model by Newton's
    /// iteration.
    #[serde(default)]
    pub second_order: Option<bool>,
}

/// The reference standards a triad names (`standards`).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadStandardsBody {
    /// The tumble stand or dividing head.
    #[serde(default)]
    pub stand: Option<String>,
    /// The thermometer the run temperatures were read with: recorded, and
    /// in a temperature model its reading's uncertainty enters every
    /// element read at a temperature (`u_T · |de/dT|`).
    #[serde(default)]
    pub thermometer: Option<String>,
    /// The local gravity value.
    #[serde(default)]
    pub gravity: Option<String>,
}

/// A triad's stand (`stand`): at least one of the two.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadStandBody {
    /// Indexing error of the dividing head, arcseconds (1σ, 0 to 3600;
    /// default 0). Known orientations only.
    #[serde(default)]
    pub angle_std_arcsec: Option<f64>,
    /// Relative uncertainty of the local gravity magnitude (0 to 0.1;
    /// default 0).
    #[serde(default)]
    pub gravity_rel_std: Option<f64>,
}

/// Orientations: given, or a named set.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum OrientationsBody {
    /// `six_faces` or `cube24`.
    Named(NamedSet),
    /// Gravity vectors in the body frame, in g.
    Vectors(Vec<[f64; 3]>),
}

/// A named set of orientations.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, ToSchema, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum NamedSet {
    /// +x, −x, +y, −y, +z, −z up.
    SixFaces,
    /// Each face up, turned 0°, 90°, 180°, 270° about the vertical: the body
    /// sees each face's gravity vector four times.
    Cube24,
}

/// One run of a triad with known orientations.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TriadRunBody {
    /// Per position, its samples of `(u_x, u_y, u_z)`.
    pub samples: Vec<Vec<[f64; 3]>>,
    /// The temperature the run was made at, °C (−100 to 200), or one per
    /// position (a chamber that drifts: the run's is their mean): for every
    /// run or for none; `POST /v1/identify/thermal/triad` groups the runs
    /// into set points by it, a triad at one temperature takes the runs'
    /// mean (every reading within 0.5 K) as its `temperature_c`.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::run_temperature)]
    pub temperature_c: Option<RunTemperature>,
}

/// A run's `temperature_c`: the run's, or one per position.
#[derive(Debug, Clone, PartialEq)]
pub enum RunTemperature {
    /// The run's, °C.
    One(f64),
    /// One per position, °C.
    Each(Vec<f64>),
}

impl<'de> Deserialize<'de> for RunTemperature {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = RunTemperature;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("the run's temperature in °C, or an array of one per position")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Self::Value, E> {
                Ok(RunTemperature::One(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Self::Value, E> {
                Ok(RunTemperature::One(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Self::Value, E> {
                Ok(RunTemperature::One(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                let mut each = Vec::new();
                while let Some(t) = seq.next_element::<f64>()? {
                    each.push(t);
                }
                Ok(RunTemperature::Each(each))
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// A continuous recording. Its static intervals count against the same
/// limit as explicit positions (360).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RecordingBody {
    /// Samples per second.
    pub rate_hz: f64,
    /// The samples of `(u_x, u_y, u_z)`, in time order.
    pub samples: Vec<[f64; 3]>,
    /// The detector's parameters (each defaulted).
    #[serde(default)]
    pub detector: Option<DetectorBody>,
    /// Each sample's temperature, °C (−100 to 200), one per sample: for
    /// `POST /v1/identify/thermal/triad` each static interval is a position
    /// at its samples' mean temperature; a triad at one temperature takes
    /// their mean (all within 0.5 K) as its `temperature_c`.
    #[serde(default)]
    pub temperature_c: Option<Vec<f64>>,
}

/// The static-interval detector's parameters.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DetectorBody {
    /// The initial still period, s (default 3, at least 0.5).
    #[serde(default)]
    pub still_s: Option<f64>,
    /// The moving-variance window, s (default 1, at least 0.1 s and 10
    /// samples).
    #[serde(default)]
    pub window_s: Option<f64>,
    /// Static where the window's variance is at most this multiple of the
    /// still period's (default 6, at least 2).
    #[serde(default)]
    pub threshold: Option<f64>,
    /// The shortest interval used, s (default 2, at least 0.5).
    #[serde(default)]
    pub min_static_s: Option<f64>,
}

impl DetectorBody {
    pub(super) fn detector(self) -> Detector {
        let d = Detector::default();
        Detector {
            still_s: self.still_s.unwrap_or(d.still_s),
            window_s: self.window_s.unwrap_or(d.window_s),
            threshold: self.threshold.unwrap_or(d.threshold),
            min_static_s: self.min_static_s.unwrap_or(d.min_static_s),
        }
    }
}

/// A checked triad submission.
#[derive(Debug, Clone)]
pub struct TriadSubmission {
    /// The triad's id.
    pub sensor_id: Option<String>,
    /// The submitting station.
    pub station_id: Option<String>,
    /// When the test was performed, as stated.
    pub performed_at: Option<Timestamp>,
    /// The outputs' unit.
    pub unit: String,
    /// What to compute.
    pub form: Form,
    /// The stand (known orientations).
    pub stand: Stand,
    /// The sensor type named, if any.
    pub sensor_type: Option<String>,
    /// What the expanded uncertainties hold fixed: the sensor type's when
    /// one judges the triad (set by the caller), else the default
    /// probability.
    pub coverage: Coverage,
    /// The reference standards named, by role (`stand`, `thermometer`,
    /// `gravity`).
    pub standards: Vec<(&'static str, String)>,
}

/// The three forms.
#[derive(Debug, Clone)]
pub enum Form {
    /// Known orientations.
    Known {
        /// Gravity vectors.
        positions: Vec<[f64; 3]>,
        /// Runs.
        runs: Vec<TriadRun>,
        /// Batches.
        batches: usize,
        /// Each axis with its `kii`.
        second_order: bool,
        /// Each run's temperature, °C, when the runs give them (all or
        /// none): given per position, their mean.
        temperatures_c: Option<Vec<f64>>,
        /// Per run, its positions' temperatures when given per position.
        position_temperatures_c: Vec<Option<Vec<f64>>>,
    },
    /// The static positions' mean outputs.
    Unknown {
        /// Per position, the mean of its samples.
        means: Vec<[f64; 3]>,
        /// Per position, its temperature, °C, when given.
        temperatures_c: Option<Vec<f64>>,
    },
    /// A recording.
    Recording {
        /// Samples per second.
        rate_hz: f64,
        /// The samples.
        samples: Vec<[f64; 3]>,
        /// The detector.
        detector: Detector,
        /// Each sample's temperature, °C, when given.
        temperatures_c: Option<Vec<f64>>,
    },
}
