//! IEEE-style normalised quantities derived from a set of coefficients.
//!
//! Dividing by the scale factor `ki` (K1) expresses the model's error terms as
//! input-referred accelerations:
//!
//! ```text
//! bias            = k0 / ki      (g)
//! misalignment_p  = kp / ki      (rad)   input axis about the output axis
//! misalignment_o  = ko / ki      (rad)   input axis about the pendulous axis
//! second order    = kii / ki     (g/g²)
//! third order     = kiii / ki    (g/g³)
//! ```
//!
//! A quantity is present only when the model has both terms and the ratio is
//! finite.

use serde::Serialize;

use crate::Term;
use crate::term::TermMap;

/// Normalised (input-referred) values; absent where the model lacks the terms.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Normalized {
    /// `k0/ki` in g.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias_g: Option<f64>,
    /// `kp/ki` in rad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub misalignment_p_rad: Option<f64>,
    /// `ko/ki` in rad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub misalignment_o_rad: Option<f64>,
    /// `kii/ki` in g/g².
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_order_g_per_g2: Option<f64>,
    /// `kiii/ki` in g/g³.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub third_order_g_per_g3: Option<f64>,
}

impl Normalized {
    /// Derives the normalised values from `coefficients`.
    pub fn from_coefficients(coefficients: &TermMap<f64>) -> Self {
        let ki = coefficients.get(Term::Ki).copied();
        let ratio = |t: Term| {
            let (num, den) = (coefficients.get(t).copied()?, ki?);
            let r = num / den;
            r.is_finite().then_some(r)
        };
        Normalized {
            bias_g: ratio(Term::K0),
            misalignment_p_rad: ratio(Term::Kp),
            misalignment_o_rad: ratio(Term::Ko),
            second_order_g_per_g2: ratio(Term::Kii),
            third_order_g_per_g3: ratio(Term::Kiii),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratios_exist_only_for_present_terms() {
        let c = TermMap(vec![(Term::K0, 0.5), (Term::Ki, -2.0), (Term::Kp, 0.01)]);
        let n = Normalized::from_coefficients(&c);
        assert_eq!(n.bias_g, Some(-0.25));
        assert_eq!(n.misalignment_p_rad, Some(-0.005));
        assert_eq!(n.misalignment_o_rad, None);
        assert_eq!(n.second_order_g_per_g2, None);
        let no_ki = TermMap(vec![(Term::K0, 0.5)]);
        assert_eq!(Normalized::from_coefficients(&no_ki), Normalized::default());
        let zero_ki = TermMap(vec![(Term::K0, 0.5), (Term::Ki, 0.0)]);
        assert_eq!(Normalized::from_coefficients(&zero_ki).bias_g, None);
    }
}
