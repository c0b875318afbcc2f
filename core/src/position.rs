//! Tumble positions: the specific force the sensor feels at each orientation.
//!
//! A position is given either by its gravity components `a = [a_i, a_p, a_o]`
//! in g, or by a dividing-head angle θ in degrees and a mount:
//!
//! ```text
//! pendulum mount (output axis on the rotation axis):    a = (−sin θ, cos θ, 0)
//! gate mount     (pendulous axis on the rotation axis): a = (−sin θ, 0, cos θ)
//! ```
//!
//! so the pendulum tumble 0°, 90°, 180°, 270° visits (0,1,0), (−1,0,0),
//! (0,−1,0), (1,0,0). Sine and cosine are evaluated after reducing θ to the
//! first quadrant, which makes multiples of 90° exact (true zeros, not
//! `6e-17`) and keeps symmetric angles exactly symmetric.

use serde::{Deserialize, Serialize};

/// Specific-force components in g along the input, pendulous and output axes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Gravity {
    /// Along the input axis, `a_i`.
    pub i: f64,
    /// Along the pendulous axis, `a_p`.
    pub p: f64,
    /// Along the output axis, `a_o`.
    pub o: f64,
}

impl Gravity {
    /// The components as `[a_i, a_p, a_o]`.
    pub fn to_array(self) -> [f64; 3] {
        [self.i, self.p, self.o]
    }

    /// Euclidean norm `sqrt(a_i² + a_p² + a_o²)`, 1 in an ideal 1 g tumble.
    pub fn norm(self) -> f64 {
        (self.i * self.i + self.p * self.p + self.o * self.o).sqrt()
    }
}

impl From<[f64; 3]> for Gravity {
    fn from([i, p, o]: [f64; 3]) -> Self {
        Gravity { i, p, o }
    }
}

impl Serialize for Gravity {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_array().serialize(s)
    }
}

impl<'de> Deserialize<'de> for Gravity {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        <[f64; 3]>::deserialize(d).map(Gravity::from)
    }
}

/// How the sensor sits on the dividing head.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mount {
    /// Output axis along the rotation axis: `a = (−sin θ, cos θ, 0)`.
    #[default]
    Pendulum,
    /// Pendulous axis along the rotation axis: `a = (−sin θ, 0, cos θ)`.
    Gate,
}

impl Mount {
    /// `da/dθ` per radian at dividing-head angle `deg` (degrees):
    /// pendulum `(−cos θ, −sin θ, 0)`, gate `(−cos θ, 0, −sin θ)`.
    pub fn derivative(self, deg: f64) -> Gravity {
        let (s, c) = sin_cos_deg(deg);
        match self {
            Mount::Pendulum => Gravity {
                i: -c,
                p: -s,
                o: 0.0,
            },
            Mount::Gate => Gravity {
                i: -c,
                p: 0.0,
                o: -s,
            },
        }
    }

    /// Gravity components at dividing-head angle `deg` (degrees).
    pub fn gravity(self, deg: f64) -> Gravity {
        let (s, c) = sin_cos_deg(deg);
        // `+ 0.0` turns −0.0 (e.g. −sin 0°) into 0.0; other values are unchanged.
        let (s, c) = (-s + 0.0, c + 0.0);
        match self {
            Mount::Pendulum => Gravity { i: s, p: c, o: 0.0 },
            Mount::Gate => Gravity { i: s, p: 0.0, o: c },
        }
    }
}

/// `(sin θ, cos θ)` for θ in degrees, exact at multiples of 90°.
///
/// θ is reduced to `r ∈ [0°, 90°)` plus a quadrant `q`, then
/// `(sin, cos)(θ) = rot_q(sin r, cos r)` with `rot` the quarter-turn table;
/// for `r > 45°`, `(sin r, cos r) = (cos(90° − r), sin(90° − r))`.
fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let turn = deg.rem_euclid(360.0);
    let quadrant = (turn / 90.0).floor();
    let rest = turn - 90.0 * quadrant;
    // Mirror the upper half of the quadrant so that complementary angles use
    // the same evaluations (sin 60° is computed as cos 30°).
    let (s, c) = if rest > 45.0 {
        let (c, s) = (90.0 - rest).to_radians().sin_cos();
        (s, c)
    } else {
        rest.to_radians().sin_cos()
    };
    // `turn < 360` so `quadrant` is 0..=3, except that rem_euclid may round up
    // to exactly 360 for tiny negative inputs, which is quadrant 4 ≡ 0.
    match quadrant as u8 % 4 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// The dividing-head rotation a position was set by: what an indexing error
/// of the stand moves (see [`crate::uncertainty`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rotation {
    /// The angle θ, in degrees.
    pub angle_deg: f64,
    /// The mount, whose axis θ turns about.
    pub mount: Mount,
}

/// One orientation of a tumble: its specific force, the rotation that set it
/// (when it was given by an angle) and an optional label.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Position {
    /// Gravity components `[a_i, a_p, a_o]` in g.
    pub a: Gravity,
    /// The dividing-head rotation, when the position was given by an angle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<Rotation>,
    /// Free-text label (e.g. `"PA down"`), echoed in results.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

impl Position {
    /// A position from explicit components `[a_i, a_p, a_o]` in g.
    pub fn from_components(a: [f64; 3], label: Option<String>) -> Self {
        Position {
            a: a.into(),
            rotation: None,
            label,
        }
    }

    /// A position from a dividing-head angle (degrees) and mount.
    pub fn from_angle(deg: f64, mount: Mount, label: Option<String>) -> Self {
        Position {
            a: mount.gravity(deg),
            rotation: Some(Rotation {
                angle_deg: deg,
                mount,
            }),
            label,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_position_pendulum_tumble_is_exact() {
        let got: Vec<[f64; 3]> = [0.0, 90.0, 180.0, 270.0]
            .iter()
            .map(|d| Mount::Pendulum.gravity(*d).to_array())
            .collect();
        assert_eq!(
            got,
            [
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
                [1.0, 0.0, 0.0]
            ]
        );
    }

    #[test]
    fn no_negative_zeros() {
        for deg in [0.0, 90.0, 180.0, 270.0, -90.0, 360.0] {
            for m in [Mount::Pendulum, Mount::Gate] {
                for x in m.gravity(deg).to_array() {
                    assert!(x != 0.0 || x.is_sign_positive(), "{m:?} {deg}: {x}");
                }
            }
        }
    }

    #[test]
    fn gate_mount_swaps_pendulous_for_output() {
        assert_eq!(Mount::Gate.gravity(0.0).to_array(), [0.0, 0.0, 1.0]);
        assert_eq!(Mount::Gate.gravity(-90.0).to_array(), [1.0, 0.0, 0.0]);
        assert_eq!(Mount::Gate.gravity(450.0).to_array(), [-1.0, 0.0, 0.0]);
    }

    /// Every quadrant, against the standard library's sine and cosine.
    #[test]
    fn angles_in_every_quadrant_follow_the_mount_formulas() {
        for deg in [
            10.0, 30.0, 60.0, 100.0, 135.0, 210.0, 240.0, 300.0, 330.0, -30.0, 725.0,
        ] {
            let (s, c) = f64::to_radians(deg).sin_cos();
            let p = Mount::Pendulum.gravity(deg);
            let g = Mount::Gate.gravity(deg);
            for (got, want) in [
                (p.i, -s),
                (p.p, c),
                (p.o, 0.0),
                (g.i, -s),
                (g.p, 0.0),
                (g.o, c),
            ] {
                assert!((got - want).abs() < 1e-15, "{deg}°: {got} vs {want}");
            }
        }
    }

    /// Up to 45° inside a quadrant the angle itself is evaluated, above it
    /// the complement (so 45° exactly gives std's sin 45° and cos 45°, which
    /// differ in the last bit).
    #[test]
    fn the_half_quadrant_rule_is_exact_at_45_degrees() {
        let (s, c) = 45f64.to_radians().sin_cos();
        assert_ne!(s, c, "sin 45° and cos 45° differ in the last bit");
        let a = Mount::Pendulum.gravity(45.0);
        assert_eq!((a.i, a.p), (-s, c));
        let (s60, c60) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let b = Mount::Pendulum.gravity(60.0);
        assert_eq!((b.i, b.p), (-s60, c60));
    }

    #[test]
    fn norms_and_the_wire_form() {
        assert_eq!(Gravity::from([1.0, 2.0, 2.0]).norm(), 3.0);
        assert_eq!(Gravity::from([2.0, 3.0, 6.0]).norm(), 7.0);
        let g: Gravity = serde_json::from_str("[0.6, -0.8, 0.0]").unwrap();
        assert_eq!(g, Gravity::from([0.6, -0.8, 0.0]));
        assert_eq!(serde_json::to_string(&g).unwrap(), "[0.6,-0.8,0.0]");
        assert!(serde_json::from_str::<Gravity>("[1, 2]").is_err());
    }

    #[test]
    fn intermediate_angles_are_symmetric_and_unit() {
        let a30 = Mount::Pendulum.gravity(30.0);
        let a150 = Mount::Pendulum.gravity(150.0);
        assert_eq!(a30.i, a150.i);
        assert_eq!(a30.p, -a150.p);
        assert!((a30.i + 0.5).abs() < 1e-15);
        for k in 0..24 {
            let g = Mount::Gate.gravity(15.0 * f64::from(k));
            assert!((g.norm() - 1.0).abs() < 1e-15);
        }
    }
}
