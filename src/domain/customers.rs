//! Who a certificate is for, and what was calibrated (issue 29 item 4):
//! customers, and the item behind each sensor id — its manufacturer, model,
//! serial number and customer.
//!
//! An item is recorded by sensor id, and may be recorded before the sensor
//! is first calibrated (when it arrives). A customer says whether it agreed
//! to a due date on its certificates (ISO/IEC 17025 §7.8.4.3: a calibration
//! certificate states a recommended interval only when agreed with the
//! customer).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_DESCRIPTION_CHARS, MAX_LABEL_CHARS};
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// The body of `PUT /v1/customers/{customer_id}`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CustomerBody {
    /// Its name, as certificates print it (one line, at most 256
    /// characters).
    #[schema(schema_with = crate::domain::schema::description)]
    pub name: String,
    /// Its address (one line, at most 256 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_description)]
    pub address: Option<String>,
    /// Whom to contact (one line, at most 256 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_description)]
    pub contact: Option<String>,
    /// Whether the customer agreed to a due date on its certificates
    /// (default: no — the certificate then states none).
    #[serde(default)]
    pub due_date_agreed: bool,
}

/// A customer as stored and served.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct Customer {
    /// Its id.
    pub customer_id: String,
    /// Its name.
    pub name: String,
    /// Its address.
    pub address: Option<String>,
    /// Whom to contact.
    pub contact: Option<String>,
    /// Whether it agreed to a due date on its certificates.
    pub due_date_agreed: bool,
    /// When it was last written.
    pub updated_at: Timestamp,
}

/// The body of `PUT /v1/sensors/{sensor_id}/item`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ItemBody {
    /// Its manufacturer (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub manufacturer: Option<String>,
    /// Its model (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub model: Option<String>,
    /// Its serial number (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub serial: Option<String>,
    /// The customer it belongs to (a customer id that exists).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_identifier)]
    pub customer: Option<String>,
}

/// The item behind a sensor id, as stored and served.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct Item {
    /// The sensor id it is calibrated under.
    pub sensor_id: String,
    /// Its manufacturer.
    pub manufacturer: Option<String>,
    /// Its model.
    pub model: Option<String>,
    /// Its serial number.
    pub serial: Option<String>,
    /// The customer it belongs to.
    pub customer: Option<String>,
    /// When it was last written.
    pub updated_at: Timestamp,
}

impl Item {
    /// "Manufacturer model, serial number S", from what is recorded.
    pub fn describe(&self) -> String {
        let name = [self.manufacturer.as_deref(), self.model.as_deref()]
            .into_iter()
            .flatten()
            .collect::<Vec<_>>()
            .join(" ");
        match (&self.serial, name.is_empty()) {
            (Some(s), true) => format!("serial number {s}"),
            (Some(s), false) => format!("{name}, serial number {s}"),
            (None, true) => "not described".to_owned(),
            (None, false) => name,
        }
    }
}

/// Checks an optional line of at most `max` characters at `at`.
fn line(errors: &mut Errors, at: Loc<'_>, value: Option<&str>, max: usize) {
    if let Some(v) = value
        && let Err(why) = check_str(v, max, Chars::Line)
    {
        errors.add(at, why);
    }
}

impl CustomerBody {
    /// Checks the body and makes the customer `customer_id` of it, written
    /// at `now`; every problem is reported.
    pub fn check(self, customer_id: String, now: Timestamp) -> Result<Customer, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        line(
            &mut errors,
            root.key("name"),
            Some(&self.name),
            MAX_DESCRIPTION_CHARS,
        );
        line(
            &mut errors,
            root.key("address"),
            self.address.as_deref(),
            MAX_DESCRIPTION_CHARS,
        );
        line(
            &mut errors,
            root.key("contact"),
            self.contact.as_deref(),
            MAX_DESCRIPTION_CHARS,
        );
        errors.finish(|| Customer {
            customer_id,
            name: self.name,
            address: self.address,
            contact: self.contact,
            due_date_agreed: self.due_date_agreed,
            updated_at: now,
        })
    }
}

impl ItemBody {
    /// Checks the body and makes the item of `sensor_id` of it, written at
    /// `now` (whether its customer exists is the caller's to ask).
    pub fn check(self, sensor_id: String, now: Timestamp) -> Result<Item, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        for (name, value) in [
            ("manufacturer", &self.manufacturer),
            ("model", &self.model),
            ("serial", &self.serial),
        ] {
            line(
                &mut errors,
                root.key(name),
                value.as_deref(),
                MAX_LABEL_CHARS,
            );
        }
        if let Some(c) = &self.customer
            && let Err(why) = check_str(c, MAX_LABEL_CHARS, Chars::Identifier)
        {
            errors.add(root.key("customer"), why);
        }
        errors.finish(|| Item {
            sensor_id,
            manufacturer: self.manufacturer,
            model: self.model,
            serial: self.serial,
            customer: self.customer,
            updated_at: now,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn now() -> Timestamp {
        Timestamp::parse("2026-11-25T00:00:00Z").unwrap()
    }

    #[test]
    fn bodies_are_checked_field_by_field() {
        let c = CustomerBody {
            name: "Acme Navigation".into(),
            address: Some("1 Gyro Way".into()),
            contact: None,
            due_date_agreed: true,
        }
        .check("ACME".into(), now())
        .unwrap();
        assert!(c.due_date_agreed);
        let e = CustomerBody {
            name: String::new(),
            address: Some("a\u{7}b".into()),
            contact: Some("x".repeat(257)),
            due_date_agreed: false,
        }
        .check("ACME".into(), now())
        .unwrap_err();
        let at: Vec<&str> = e.errors.iter().map(|f| f.pointer.as_str()).collect();
        assert_eq!(at, ["/name", "/address", "/contact"]);
        let e = ItemBody {
            manufacturer: Some("x".repeat(65)),
            model: None,
            serial: Some("SN 1".into()),
            customer: Some("not an id".into()),
        }
        .check("S-1".into(), now())
        .unwrap_err();
        let at: Vec<&str> = e.errors.iter().map(|f| f.pointer.as_str()).collect();
        assert_eq!(at, ["/manufacturer", "/customer"]);
    }

    #[test]
    fn an_item_describes_itself_with_what_is_known() {
        let item = |m: Option<&str>, model: Option<&str>, s: Option<&str>| Item {
            sensor_id: "S".into(),
            manufacturer: m.map(Into::into),
            model: model.map(Into::into),
            serial: s.map(Into::into),
            customer: None,
            updated_at: now(),
        };
        assert_eq!(
            item(Some("Honeywell"), Some("QA-3000"), Some("1234")).describe(),
            "Honeywell QA-3000, serial number 1234"
        );
        assert_eq!(item(None, Some("QA-3000"), None).describe(), "QA-3000");
        assert_eq!(
            item(None, None, Some("1234")).describe(),
            "serial number 1234"
        );
        assert_eq!(item(None, None, None).describe(), "not described");
    }
}
