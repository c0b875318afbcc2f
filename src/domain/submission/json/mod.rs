//! The JSON submission read straight into a [`Draft`]: numbers go into
//! `Vec<f64>` as they are parsed, values of the wrong kind are recorded with
//! their pointer and skipped, and every count is checked while reading, so
//! that memory stays proportional to what the limits allow rather than to
//! what a client sends.

use accelcal_core::{Gravity, Mount, Term};
use serde::de::{DeserializeSeed, IgnoredAny, MapAccess, SeqAccess};

mod positions;
mod runs;

use self::positions::Positions;
use self::runs::Runs;
use super::FIELDS;
use super::draft::{Draft, Slot, StandDraft, StandardsDraft};
use super::node::{Any, Node, Scalar, Seed, elements, keep, scalar_fields};
use crate::domain::field::{Errors, Loc};
use crate::domain::limits::*;
use crate::domain::text::{Chars, echo};
use crate::domain::timestamp::Timestamp;

/// Reads a JSON submission; `Err` only for a syntax error (not JSON), with
/// the parser's message.
pub fn read(bytes: &[u8]) -> Result<Draft, String> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let mut draft = Draft::default();
    Seed(Top { draft: &mut draft })
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| e.to_string())?;
    Ok(draft)
}

/// The top-level object.
struct Top<'a> {
    draft: &'a mut Draft,
}

impl<'de> Node<'de> for Top<'_> {
    type Out = ();

    fn scalar(self, value: Scalar) {
        self.draft.not_an_object = true;
        self.draft.errors.add(
            Loc::Root,
            format!("must be an object, not {}", value.kind()),
        );
    }

    fn map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let d = self.draft;
        let root = Loc::Root;
        let mut seen = [false; FIELDS.len()];
        while let Some(key) = map.next_key::<String>()? {
            let at = root.key(&key);
            let Some(field) = FIELDS.iter().position(|f| *f == key) else {
                d.errors.add(
                    at,
                    format!(
                        "unknown field `{}`; expected one of: {}",
                        echo(&key),
                        FIELDS.join(", ")
                    ),
                );
                map.next_value::<IgnoredAny>()?;
                continue;
            };
            if std::mem::replace(&mut seen[field], true) {
                d.errors
                    .add(at, format!("duplicate key `{key}`: given more than once"));
                map.next_value::<IgnoredAny>()?;
                continue;
            }
            let value = |v: Scalar| (v != Scalar::Null).then_some(v);
            let errors = &mut d.errors;
            match key.as_str() {
                "positions" => d.positions = map.next_value_seed(Seed(Positions { errors, at }))?,
                "runs" => d.runs = map.next_value_seed(Seed(Runs { errors, at }))?,
                "model" => d.model = map.next_value_seed(Seed(ModelNode { errors, at }))?,
                "stand" => d.stand = map.next_value_seed(Seed(StandNode { errors, at }))?,
                "standards" => {
                    d.standards = map.next_value_seed(Seed(StandardsNode { errors, at }))?
                }
                name => {
                    let Some(v) = value(map.next_value_seed(Seed(Any))?) else {
                        continue;
                    };
                    match name {
                        "sensor_id" => {
                            d.sensor_id =
                                slot(errors, at, v.string(MAX_ID_CHARS, Chars::Identifier))
                        }
                        "station_id" => {
                            d.station_id =
                                slot(errors, at, v.string(MAX_ID_CHARS, Chars::Identifier))
                        }
                        "unit" => d.unit = slot(errors, at, v.string(MAX_UNIT_CHARS, Chars::Line)),
                        "notes" => {
                            d.notes = slot(errors, at, v.string(MAX_NOTES_CHARS, Chars::Text))
                        }
                        "batches" => d.batches = slot(errors, at, v.integer(1, MAX_BATCHES)),
                        "mount" => d.mount = slot(errors, at, mount(v)),
                        "performed_at" => d.performed_at = slot(errors, at, performed_at(v)),
                        "sensor_type" => {
                            d.sensor_type =
                                slot(errors, at, v.string(MAX_ID_CHARS, Chars::Identifier))
                        }
                        "item_received_at" => {
                            d.item_received_at = slot(errors, at, performed_at(v))
                        }
                        "item_condition" => {
                            d.item_condition =
                                slot(errors, at, v.string(MAX_DESCRIPTION_CHARS, Chars::Line))
                        }
                        other => unreachable_field(other),
                    }
                }
            }
        }
        Ok(())
    }
}

/// Every name in [`FIELDS`] has a branch above; this documents it.
fn unreachable_field(name: &str) {
    debug_assert!(false, "field `{name}` is listed but not read");
}

fn slot<T>(errors: &mut Errors, at: Loc<'_>, read: Result<T, String>) -> Slot<T> {
    Slot::from_read(keep(errors, at, read))
}

/// `"pendulum"` or `"gate"`.
pub fn mount(v: Scalar) -> Result<Mount, String> {
    match v {
        Scalar::Str(s) if s == "pendulum" => Ok(Mount::Pendulum),
        Scalar::Str(s) if s == "gate" => Ok(Mount::Gate),
        _ => Err("must be \"pendulum\" or \"gate\"".into()),
    }
}

/// An RFC 3339 date-time.
pub fn performed_at(v: Scalar) -> Result<Timestamp, String> {
    let s = v.string(64, Chars::Line)?;
    Timestamp::parse(&s).map_err(|e| e.to_string())
}

/// A term name that is not already in `terms`.
pub fn term(v: Scalar, terms: &[Term]) -> Result<Term, String> {
    let Scalar::Str(name) = v else {
        return Err("must be a term name such as \"k0\"".into());
    };
    match name.parse::<Term>() {
        Ok(t) if terms.contains(&t) => Err(format!("term `{t}` is listed twice")),
        Ok(t) => Ok(t),
        Err(_) => Err(unknown_term(&name)),
    }
}

/// The refusal of an unknown term name, with a hint for a near miss: the
/// paper's capitals (`K0`, `Ki`) or a stray space.
pub fn unknown_term(name: &str) -> String {
    let near = name.trim().to_ascii_lowercase();
    let hint = match near.parse::<Term>() {
        Ok(t) => format!("; did you mean `{t}`? term names are lower case, as in the README"),
        Err(_) => String::new(),
    };
    format!(
        "unknown term `{}`; expected one of k0, ki, kp, ko, kio, kop, kpi, kii, kpp, koo, kiii{hint}",
        echo(name)
    )
}

/// A run temperature, °C.
pub fn temperature(v: &Scalar) -> Result<f64, String> {
    let t = v.number(f64::MAX)?;
    if TEMPERATURE_C.contains(&t) {
        return Ok(t);
    }
    // 223.15–473.15 K are −50–200 °C: a station reporting kelvin.
    let kelvin = if (223.15..=473.15).contains(&t) {
        format!(
            "; {t} looks like kelvin: send degrees Celsius ({:.2} °C)",
            t - 273.15
        )
    } else {
        String::new()
    };
    Err(format!(
        "must be a temperature from {} to {} °C{kelvin}",
        TEMPERATURE_C.start(),
        TEMPERATURE_C.end()
    ))
}

/// `stand.angle_std_arcsec`.
pub fn angle_std(v: &Scalar) -> Result<f64, String> {
    bounded(v, MAX_ANGLE_STD_ARCSEC)
}

/// `stand.gravity_rel_std`.
pub fn gravity_std(v: &Scalar) -> Result<f64, String> {
    bounded(v, MAX_GRAVITY_REL_STD)
}

/// A number from 0 to `max`.
fn bounded(v: &Scalar, max: f64) -> Result<f64, String> {
    match v.number(max) {
        Ok(x) if x >= 0.0 => Ok(x),
        _ => Err(format!("must be a number from 0 to {max}")),
    }
}

/// What an optional object member that came as a scalar reads as: absent
/// when null, else invalid, saying so.
fn optional_object<T>(errors: &mut Errors, at: Loc<'_>, v: Scalar) -> Slot<T> {
    if v == Scalar::Null {
        return Slot::Absent;
    }
    errors.add(at, format!("must be an object, not {}", v.kind()));
    Slot::Invalid
}

/// `stand`: an object of `id`, `angle_std_arcsec`, `gravity_rel_std`.
struct StandNode<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for StandNode<'_> {
    type Out = Slot<StandDraft>;
    fn scalar(self, v: Scalar) -> Self::Out {
        optional_object(self.errors, self.at, v)
    }
    fn map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Out, A::Error> {
        const KEYS: [&str; 3] = ["id", "angle_std_arcsec", "gravity_rel_std"];
        let Some([id, angle, gravity]) = scalar_fields(map, self.errors, self.at, KEYS)? else {
            return Ok(Slot::Invalid);
        };
        let (errors, at) = (self.errors, self.at);
        let mut ok = true;
        let mut stand = StandDraft::default();
        if let Some(v) = id {
            stand.id = keep(
                errors,
                at.key(KEYS[0]),
                v.string(MAX_ID_CHARS, Chars::Identifier),
            );
            ok &= stand.id.is_some();
        }
        if let Some(v) = angle {
            stand.angle_std_arcsec = keep(errors, at.key(KEYS[1]), angle_std(&v));
            ok &= stand.angle_std_arcsec.is_some();
        }
        if let Some(v) = gravity {
            stand.gravity_rel_std = keep(errors, at.key(KEYS[2]), gravity_std(&v));
            ok &= stand.gravity_rel_std.is_some();
        }
        Ok(if ok {
            Slot::Value(stand)
        } else {
            Slot::Invalid
        })
    }
}

/// The roles a submission's `standards` name a standard in.
pub const STANDARD_ROLES: [&str; 3] = ["stand", "thermometer", "gravity"];

/// `standards`: an object of `stand`, `thermometer`, `gravity`, each a
/// standard's id.
struct StandardsNode<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for StandardsNode<'_> {
    type Out = Slot<StandardsDraft>;
    fn scalar(self, v: Scalar) -> Self::Out {
        optional_object(self.errors, self.at, v)
    }
    fn map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Out, A::Error> {
        let Some(ids) = scalar_fields(map, self.errors, self.at, STANDARD_ROLES)? else {
            return Ok(Slot::Invalid);
        };
        let (errors, at) = (self.errors, self.at);
        let mut ok = true;
        let mut ids = ids.into_iter();
        let [stand, thermometer, gravity] = std::array::from_fn(|k| {
            let given = ids.next().flatten()?;
            let id = keep(
                errors,
                at.key(STANDARD_ROLES[k]),
                given.string(MAX_ID_CHARS, Chars::Identifier),
            );
            ok &= id.is_some();
            id
        });
        let standards = StandardsDraft {
            stand,
            thermometer,
            gravity,
        };
        Ok(if ok {
            Slot::Value(standards)
        } else {
            Slot::Invalid
        })
    }
}

/// Gravity components `[a_i, a_p, a_o]` in g, with a norm near 1 g.
pub fn gravity(a: [f64; 3]) -> Result<Gravity, String> {
    let g = Gravity::from(a);
    if GRAVITY_NORM.contains(&g.norm()) {
        Ok(g)
    } else {
        Err(format!(
            "gravity components [a_i, a_p, a_o] must have a norm near 1 g ({}–{}), not {:.6}",
            GRAVITY_NORM.start(),
            GRAVITY_NORM.end(),
            g.norm()
        ))
    }
}

struct ModelNode<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for ModelNode<'_> {
    type Out = Slot<Vec<Term>>;
    fn scalar(self, v: Scalar) -> Self::Out {
        if v == Scalar::Null {
            return Slot::Absent;
        }
        self.errors
            .add(self.at, format!("must be an array, not {}", v.kind()));
        Slot::Invalid
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let mut terms: Vec<Term> = Vec::new();
        let mut ok = true;
        let at = self.at;
        let read = elements(
            seq,
            self.errors,
            at,
            (1, Term::ALL.len()),
            |errors, k, seq| {
                let Some(v) = seq.next_element_seed(Seed(Any))? else {
                    return Ok(None);
                };
                match term(v, &terms) {
                    Ok(t) => terms.push(t),
                    Err(why) => {
                        errors.add(at.index(k), why);
                        ok = false;
                    }
                }
                Ok(Some(Some(())))
            },
        )?;
        Ok(if read.is_some() && ok {
            Slot::Value(terms)
        } else {
            Slot::Invalid
        })
    }
}

#[cfg(test)]
mod tests;
