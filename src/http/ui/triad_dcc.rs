//! The Digital Calibration Certificate of a triad's calibration (issue 30):
//! the administrative data of any calibration's DCC ([`super::dcc`]: the
//! laboratory, the item, the persons responsible, the customer, the
//! statements), with the triad's results — every measured element of `b`
//! and `S` (and `S2`) as a D-SI `si:real` in the output's unit, rounded to
//! its expanded uncertainty with the coverage factor and probability, and
//! a judged element's conformity.
//!
//! **Units.** `u = b + S g` with `g` the specific force in multiples of the
//! local g (unit one), so `b`, `S` and `S2` are all in the output's unit,
//! as a single axis's `k0` and `ki` are. `T = S⁻¹`, what firmware applies,
//! is derived from `S`, not measured: the description names it and the
//! calibration's exports carry it. A triad found from the gravity magnitude
//! has `S_xy`, `S_xz`, `S_yz` zero by its frame convention: not measured,
//! so not listed, and the description says so.

use super::certificate::{Context, PAPER};
use super::dcc::{Admin, Judged, Judgement, conditions, document, dsi_unit, meta_data, real, rich};
use super::triad_result::TriadDoc;
use super::xml::Xml;
use crate::domain::triad::{FIXED_BY_CONVENTION, KNOWN_ORIENTATIONS};
use crate::store::AXES;

/// What element `name` of axis `m` (column `k` for `S`) is.
fn meaning(matrix: &str, m: usize, k: usize) -> String {
    let axis = AXES[m];
    match matrix {
        "b" => format!("bias of the {axis} axis"),
        "S2" => format!("second-order coefficient of the {axis} axis (its output per g² along it)"),
        _ if k == m => format!("scale factor of the {axis} axis"),
        _ => format!(
            "sensitivity of the {axis} axis to specific force along {} (misalignment)",
            AXES[k]
        ),
    }
}

/// The DCC of triad `d` ([`super::dcc::issuable`] must have passed).
pub fn render(d: &TriadDoc, c: &Context) -> String {
    let admin = Admin {
        id: d.id,
        sensor_id: &d.sensor_id,
        item: "Accelerometer triad",
        performed_at: &d.performed_at,
        item_received_at: None,
        item_condition: None,
        supersedes: d.supersedes.as_ref(),
        standards: &d.standards,
        judged: d.decision.as_ref().map(|dec| {
            Judged::of(
                &dec.rule,
                &dec.verdict,
                dec.elements
                    .values()
                    .map(|e| (e.verdict.as_str(), e.value, e.min, e.max)),
            )
        }),
        due_at: d.due_at.as_deref(),
    };
    document(&admin, c, |x| results(x, d))
}

/// One measured element.
struct Element {
    /// `b_x`, `S_yz`, `S2_z`.
    name: String,
    /// `b`, `S` or `S2`.
    matrix: &'static str,
    /// Its axis (row).
    m: usize,
    /// Its column (`m` for a vector).
    k: usize,
    /// Its value.
    value: f64,
    /// Its expanded uncertainty, when stated.
    expanded: Option<f64>,
}

/// The measured elements in order: `b`, `S` by rows (without the frame
/// convention's zeros), `S2`.
fn elements(d: &TriadDoc) -> Vec<Element> {
    let known = d.method == KNOWN_ORIENTATIONS;
    let vector = |matrix, v: [f64; 3], u: Option<[f64; 3]>| {
        (0..3).map(move |m| Element {
            name: format!("{matrix}_{}", AXES[m]),
            matrix,
            m,
            k: m,
            value: v[m],
            expanded: u.map(|u| u[m]),
        })
    };
    let mut out: Vec<Element> = vector("b", d.b, d.b_expanded).collect();
    for m in 0..3 {
        for k in 0..3 {
            if !known && FIXED_BY_CONVENTION.contains(&(m, k)) {
                continue;
            }
            out.push(Element {
                name: format!("S_{}{}", AXES[m], AXES[k]),
                matrix: "S",
                m,
                k,
                value: d.s[m][k],
                expanded: d.s_expanded.map(|u| u[m][k]),
            });
        }
    }
    if let Some(s2) = d.s2 {
        out.extend(vector("S2", s2, d.s2_expanded));
    }
    out
}

/// The triad's `dcc:measurementResult`.
fn results(x: &mut Xml, d: &TriadDoc) {
    let unit = dsi_unit(&d.unit);
    let known = d.method == KNOWN_ORIENTATIONS;
    let statement = d.statement();
    let model = if d.s2.is_some() {
        "u = b + S g + S2 ⊙ g² (S2_m g_m² on axis m)"
    } else {
        "u = b + S g"
    };
    let description = format!(
        "The triad's static model {model}: u the three outputs in {}, g the specific force in the \
         sensor's body frame in multiples of the local g (unit one), so b, S{} are in the output's \
         unit; row m of S is axis m. Compensation applies T = S⁻¹ (g = T (u − b)), derived from S \
         and carried by the calibration's exports. {}Values are rounded to the second significant \
         digit of their expanded uncertainty.",
        d.unit,
        if d.s2.is_some() { " and S2" } else { "" },
        if known {
            ""
        } else {
            "The sensor's x axis defines the frame's x axis and its xy-plane the frame's xy-plane, \
             so S_xy, S_xz and S_yz are zero by this convention: not measured, not listed. "
        }
    );
    let method = if known {
        format!(
            "Tumble test in {} known orientations: each axis's row of S and element of b are that \
             axis's single-axis calibration over the shared positions, identified per run by least \
             squares and fused by batch estimation. Uncertainty after the GUM per axis: the fused \
             standard error, the stand's indexing error, the uncertainty of gravity and, when the \
             lack-of-fit test finds the model short of the data, the model's own standard error, \
             combined in quadrature and expanded{}.",
            d.residuals.len(),
            statement
        )
    } else {
        format!(
            "Multi-position test in {} static positions of unknown orientation: b and a \
             lower-triangular T = S⁻¹ found from the gravity magnitude (‖T (ū − b)‖ = 1) by \
             Levenberg–Marquardt. Uncertainty after the GUM per element: the fit's standard error \
             (its Jacobian, the residuals' scatter on {} degrees of freedom; S's propagated from T's \
             covariance) and the uncertainty of gravity, combined in quadrature and expanded{}; the \
             orientations' own errors do not enter.",
            d.residuals.len(),
            d.fit.as_ref().map_or(0, |f| f.degrees_of_freedom),
            if d.expanded() {
                statement
            } else {
                " (none: no degree of freedom left)".to_owned()
            }
        )
    };
    x.el("dcc:measurementResult", |x| {
        rich(x, "dcc:name", "Static model of the accelerometer triad");
        rich(x, "dcc:description", &description);
        x.el("dcc:usedMethods", |x| {
            x.el("dcc:usedMethod", |x| {
                rich(x, "dcc:name", if known {
                            "Tumble test in known orientations, each axis by least squares per run and \
                             batch-estimation fusion"
                        } else {
                            "Multi-position calibration from the gravity magnitude (Levenberg–Marquardt)"
                        });
                rich(x, "dcc:description", &method);
                x.text("dcc:norm", "ISO/IEC Guide 98-3 (GUM)");
                if known {
                    x.text("dcc:reference", PAPER);
                }
            })
        });
        super::dcc::equipment(x, &d.standards);
        conditions(x, None, &d.standards);
        x.el("dcc:results", |x| {
            x.el("dcc:result", |x| {
                rich(x, "dcc:name", "Bias b and scale-and-misalignment matrix S");
                x.el("dcc:data", |x| {
                    for e in elements(d) {
                        let covered = d.covered(&e.name);
                        let judged = d.decision.as_ref().and_then(|dec| {
                            let j = dec.elements.get(&e.name)?;
                            Some(Judgement::of(&dec.rule, (&j.verdict, j.value, j.min, j.max)))
                        });
                        x.el("dcc:quantity", |x| {
                            rich(x, "dcc:name", &format!(
                                        "{} — {} ({})",
                                        e.name,
                                        meaning(e.matrix, e.m, e.k),
                                        d.unit
                                    ));
                            real(x, &e.name, e.value, &unit, e.expanded.zip(covered));
                            meta_data(x, covered.filter(|c| c.combined.is_finite()), &d.unit, judged);
                        });
                    }
                })
            })
        });
    });
}
