//! Recording what the laboratory defines — a sensor type, a reference
//! standard (its certificate joining the earlier ones), a customer, an
//! item, and which type a sensor is — each checked by the domain before,
//! written with its audit entry in one transaction, and (the records but a
//! sensor's type) conditional on the record as the writer last read it.

use super::{Error, Lab};
use crate::domain::audit::Actor;
use crate::domain::auth::Principal;
use crate::domain::customers::{Customer, Item};
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::sensor_types::SensorType;
use crate::domain::standards::Standard;
use crate::domain::text::{Chars, check_str, echo};
use crate::store::{Precondition, Put};

/// Records sensor type `t` for `principal`, if `pre` holds.
pub async fn sensor_type(
    lab: &Lab,
    principal: &Principal,
    t: SensorType,
    pre: Precondition,
) -> Result<Put<SensorType>, Error> {
    let id = t.type_id.clone();
    let put = lab
        .store
        .put_sensor_type(t, Actor::from(principal), pre)
        .await?;
    tracing::info!(sensor_type = %id, created = put.created(), by = %principal.id, "sensor type written");
    Ok(put)
}

/// Records standard `s` for `principal`, if `pre` holds: the certificate it
/// replaces joins its earlier ones in the store's transaction, so that two
/// writes at once never lose one.
pub async fn standard(
    lab: &Lab,
    principal: &Principal,
    s: Standard,
    pre: Precondition,
) -> Result<Put<Standard>, Error> {
    let id = s.standard_id.clone();
    let put = lab
        .store
        .put_standard(s, Actor::from(principal), pre)
        .await?;
    tracing::info!(standard = %id, created = put.created(), by = %principal.id, "standard written");
    Ok(put)
}

/// Records customer `c` for `principal`, if `pre` holds.
pub async fn customer(
    lab: &Lab,
    principal: &Principal,
    c: Customer,
    pre: Precondition,
) -> Result<Put<Customer>, Error> {
    let id = c.customer_id.clone();
    let put = lab
        .store
        .put_customer(c, Actor::from(principal), pre)
        .await?;
    tracing::info!(customer = %id, created = put.created(), by = %principal.id, "customer written");
    Ok(put)
}

/// Records item `item` for `principal`, if `pre` holds: the customer it
/// names must be recorded first (`/customer` otherwise).
pub async fn item(
    lab: &Lab,
    principal: &Principal,
    item: Item,
    pre: Precondition,
) -> Result<Put<Item>, Error> {
    if let Some(c) = &item.customer
        && lab.store.customer(c.clone()).await?.is_none()
    {
        return Err(Error::invalid(
            "/customer",
            format!(
                "no customer `{}`; an admin records it first (PUT /v1/customers/{})",
                echo(c),
                echo(c)
            ),
        ));
    }
    let id = item.sensor_id.clone();
    let put = lab
        .store
        .put_item(item, Actor::from(principal), pre)
        .await?;
    tracing::info!(sensor = %id, created = put.created(), by = %principal.id, "item written");
    Ok(put)
}

/// Gives sensor `sensor_id` the type `type_id`, by `principal`: the type
/// must be recorded (`/sensor_type` otherwise). Whether the sensor was
/// found.
pub async fn retype(
    lab: &Lab,
    principal: &Principal,
    sensor_id: &str,
    type_id: String,
) -> Result<bool, Error> {
    if check_str(&type_id, MAX_ID_CHARS, Chars::Identifier).is_err()
        || lab.store.sensor_type(type_id.clone()).await?.is_none()
    {
        return Err(Error::invalid(
            "/sensor_type",
            format!("no sensor type `{}`", echo(&type_id)),
        ));
    }
    let found = lab
        .store
        .assign_sensor_type(
            sensor_id.to_owned(),
            type_id.clone(),
            Actor::from(principal),
        )
        .await?;
    if found {
        tracing::info!(sensor_id = %sensor_id, sensor_type = %type_id, by = %principal.id, "sensor type assigned");
    }
    Ok(found)
}
