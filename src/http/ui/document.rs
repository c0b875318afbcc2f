//! What a calibration of any kind yields for its documents: a
//! [`Document`] — its list of [`Quantity`] (name, value, standard error,
//! expanded uncertainty with how it was formed, unit, limits) and the
//! few passages only its kind can write (the facts, the method, the
//! sections beside the results). The printed certificate
//! ([`super::certificate::render`]) and the DCC ([`super::dcc::render`])
//! are written once over it; each kind builds its document in its own
//! module ([`super::kinds`]).
//!
//! A plain struct rather than a trait: the renderers need the same few
//! things of every kind, a kind's module fills them in one function, and a
//! document is data a test can build and compare.

use maud::Markup;

use super::result::Covered;

/// One measured (or fixed) quantity of a calibration: a coefficient of a
/// single axis's model, an element of a triad's `b`, `S` or `S2`.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    /// `k0`, `b_x`, `S_yz`.
    pub name: String,
    /// What it is, in words (`bias`, `scale factor of the x axis`).
    pub meaning: String,
    /// Its value.
    pub value: f64,
    /// Its statistical standard error, when stated.
    pub std_error: Option<f64>,
    /// Its expanded uncertainty `U`, when stated.
    pub expanded: Option<f64>,
    /// How `U` was formed (`u_c`, `ν_eff`, `k`, `p`); `u_c` may be NaN
    /// for a triad stored before each element stated it, and is then not
    /// shown.
    pub covered: Option<Covered>,
    /// Its unit as the printed certificate states it (`mA/g`, `mA per g`).
    pub unit: String,
    /// Its unit with the specific force a ratio (unit one), as the DCC
    /// names it.
    pub dcc_unit: String,
    /// The power of the kelvin it is per: a temperature model's `a_d` is
    /// in the coefficient's unit per K^d (0 for every other quantity).
    pub per_kelvin: i32,
    /// Its judgement against the sensor type's limits, when judged.
    pub limited: Option<Limited>,
    /// Why it is not measured but fixed (a triad's `S_xy` from the
    /// gravity magnitude: "by the frame convention"): the printed
    /// certificate lists it as such, the DCC leaves it out.
    pub fixed: Option<&'static str>,
}

impl Quantity {
    /// `u_c`, when stated and finite.
    pub fn combined(&self) -> Option<f64> {
        self.covered.map(|c| c.combined).filter(|c| c.is_finite())
    }
}

/// A quantity judged against limits.
#[derive(Debug, Clone, PartialEq)]
pub struct Limited {
    /// `pass`, `conditional` or `fail`.
    pub verdict: String,
    /// The value judged.
    pub value: f64,
    /// Lower limit.
    pub min: Option<f64>,
    /// Upper limit.
    pub max: Option<f64>,
}

/// What the quantities of a kind are called in a table's first column and
/// its rows' data attribute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// A single axis's coefficients (`data-term`).
    Term,
    /// A triad's elements (`data-element`).
    Element,
}

/// A calibration of any kind, as its certificate and DCC read it.
pub struct Document<'a> {
    /// Its administrative data (the DCC's, and the printed frame's).
    pub admin: Admin<'a>,
    /// After the number in the printed running header: the sensor (and
    /// its kind).
    pub running: String,
    /// Its quantities, in the order the documents list them.
    pub quantities: Vec<Quantity>,
    /// What the printed certificate says that only this kind can.
    pub printed: Printed,
    /// What the DCC's measurement result says that only this kind can.
    pub dcc: DccText,
}

/// The printed certificate's passages of one kind, in the order the
/// certificate places them around its shared sections.
pub struct Printed {
    /// The facts after the customer and the item.
    pub facts: Markup,
    /// Before the method (a single axis: the environmental conditions and
    /// the standards).
    pub before_method: Markup,
    /// The method's paragraph.
    pub method: Markup,
    /// The results table's accessible name.
    pub label: &'static str,
    /// Its caption.
    pub caption: Markup,
    /// What its rows are.
    pub column: Column,
    /// After the results (a single axis's budget, a triad's `T`).
    pub after_results: Markup,
    /// The conformity section's content, when judged.
    pub conformity: Option<Markup>,
    /// The as-found section's content, when compared.
    pub as_found: Option<Markup>,
    /// Before the traceability (a triad: the standards).
    pub before_traceability: Markup,
    /// What computed it, when recorded.
    pub computed_by: Option<String>,
}

/// The DCC measurement result's texts of one kind.
pub struct DccText {
    /// The result's name.
    pub name: &'static str,
    /// Its description: the model and its units.
    pub description: String,
    /// The method's name.
    pub method_name: &'static str,
    /// The method's description.
    pub method: String,
    /// The method's published reference, when it follows one.
    pub reference: Option<&'static str>,
    /// The runs' temperatures, °C, when recorded; a temperature model's
    /// set points.
    pub temperatures: Option<Vec<f64>>,
    /// A temperature model's `T_ref`, °C: the temperatures are then its
    /// valid range.
    pub reference_c: Option<f64>,
    /// The output's unit, which every quantity's value is stated in (the
    /// specific force a ratio).
    pub unit: String,
    /// The name of the list of quantities.
    pub results_name: &'static str,
}

/// A calibration of any kind, as its page shows it: the page's head,
/// facts, links and review are written once ([`super::calibration::page`]),
/// around what only the kind shows.
pub struct Page<'a> {
    /// The calibration.
    pub id: uuid::Uuid,
    /// Its sensor.
    pub sensor_id: &'a str,
    /// The title before "of" (`Calibration`, `Triad calibration`).
    pub title: &'static str,
    /// The last crumb of the path (`calibration`, `triad calibration`).
    pub noun: &'static str,
    /// Beside the title, for a kind that shows its verdict there (empty
    /// when not judged).
    pub verdict: Option<Markup>,
    /// The calibration it supersedes.
    pub supersedes: Option<&'a crate::domain::review::Supersedes>,
    /// When performed (RFC 3339).
    pub performed_at: &'a str,
    /// The station.
    pub station_id: Option<&'a str>,
    /// When received (RFC 3339).
    pub received_at: &'a str,
    /// The facts after the id, the station and the receipt.
    pub facts: Markup,
    /// Files to download before the documents' links.
    pub downloads: Option<Markup>,
    /// Whether it has a certificate and a DCC to link to.
    pub certified: bool,
    /// The kind's sections, before the review.
    pub sections: Markup,
}

/// What the DCC's administrative data reads of a calibration, of either
/// kind (the printed certificate's frame reads it too).
pub struct Admin<'a> {
    /// The calibration.
    pub id: uuid::Uuid,
    /// The item's sensor id.
    pub sensor_id: &'a str,
    /// What the item is called (`Accelerometer`, `Accelerometer triad`).
    pub item: &'static str,
    /// When performed (RFC 3339).
    pub performed_at: &'a str,
    /// When the item was received, if stated.
    pub item_received_at: Option<&'a str>,
    /// Its condition on receipt, if stated.
    pub item_condition: Option<&'a str>,
    /// The calibration it supersedes.
    pub supersedes: Option<&'a crate::domain::review::Supersedes>,
    /// The reference standards, as used.
    pub standards: &'a [crate::domain::standards::UsedStandard],
    /// The decision, when judged.
    pub judged: Option<Judged<'a>>,
    /// The due date, when judged.
    pub due_at: Option<&'a str>,
}

/// The statement of conformity of a judged calibration.
pub struct Judged<'a> {
    /// `simple` or `guarded`.
    pub rule: &'a str,
    /// The worst verdict.
    pub verdict: &'a str,
    /// The worst DCC conformity of the limited terms or elements.
    pub worst: &'static str,
}

impl<'a> Judged<'a> {
    /// The statement of a decision whose limited quantities give
    /// `(verdict, value, min, max)`.
    pub fn of(
        rule: &'a str,
        verdict: &'a str,
        each: impl Iterator<Item = (&'a str, f64, Option<f64>, Option<f64>)>,
    ) -> Self {
        const ORDER: [&str; 4] = ["pass", "conditionalPass", "conditionalFail", "fail"];
        let worst = each
            .map(|(v, x, min, max)| conformity(v, x, min, max))
            .max_by_key(|c| ORDER.iter().position(|x| x == c))
            .unwrap_or("pass");
        Judged {
            rule,
            verdict,
            worst,
        }
    }
}

/// The DCC conformity of a decision's verdict: `conditional` splits by
/// whether the value itself lies within the limits.
pub fn conformity(verdict: &str, value: f64, min: Option<f64>, max: Option<f64>) -> &'static str {
    match verdict {
        "pass" => "pass",
        "fail" => "fail",
        _ if min.is_none_or(|m| value >= m) && max.is_none_or(|m| value <= m) => "conditionalPass",
        _ => "conditionalFail",
    }
}
