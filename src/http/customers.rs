//! Customers (`PUT` by admins, read by everyone) and the item behind each
//! sensor id (issue 29 item 4): who a certificate is for, and what was
//! calibrated.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::Response;
use serde::Serialize;
use utoipa::ToSchema;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::conditional::{precondition, tagged, written};
use super::lookup::path_identifier;
use super::problem::Problem;
use crate::app::definitions;
use crate::domain::auth::{Principal, Role};
use crate::domain::customers::{Customer, CustomerBody, Item, ItemBody};
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::text::{Chars, check_str, echo};
use crate::domain::timestamp::Timestamp;
use crate::store::conditional::etag;

fn unknown_customer(customer_id: &str) -> Problem {
    Problem::not_found(format!("no customer `{}`", echo(customer_id)))
}

/// `PUT /v1/customers/{customer_id}` (admin): 201 when created, 200 when
/// replaced.
#[utoipa::path(
    put,
    path = "/v1/customers/{customer_id}",
    tag = "customers",
    operation_id = "putCustomer",
    summary = "Create or replace a customer (admin).",
    params(("customer_id" = crate::domain::schema::Identifier, Path, description = "The customer's id."),
        super::openapi::ConditionalHeaders),
    request_body(content((CustomerBody = "application/json",
        example = json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way, 80331 Munich",
            "contact": "Dr. K. Lee", "due_date_agreed": true})))),
    responses(
        (status = 200, description = "Replaced.", body = Customer, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 201, description = "Created.", body = Customer, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        (status = 412, response = super::openapi::PreconditionFailed),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put_customer(
    State(state): State<AppState>,
    principal: Principal,
    Path(customer_id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&customer_id, "customer")?;
    let pre = precondition(&headers)?;
    let c = body
        .json::<CustomerBody>()?
        .check(customer_id, Timestamp::now())?;
    written(
        definitions::customer(&state.lab, &principal, c, pre).await?,
        "customer",
    )
}

/// A list of customers.
#[derive(Debug, Serialize, ToSchema)]
pub struct CustomerList {
    /// Every customer, in id order.
    items: Vec<Customer>,
}

/// `GET /v1/customers`.
#[utoipa::path(
    get,
    path = "/v1/customers",
    tag = "customers",
    operation_id = "listCustomers",
    summary = "Every customer.",
    responses(
        (status = 200, description = "The customers.", body = CustomerList),
        super::openapi::Always,
    )
)]
pub async fn list_customers(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<CustomerList>, Problem> {
    require(&principal, Role::Reader)?;
    Ok(Json(CustomerList {
        items: state.store.customers().await?,
    }))
}

/// `GET /v1/customers/{customer_id}`.
#[utoipa::path(
    get,
    path = "/v1/customers/{customer_id}",
    tag = "customers",
    operation_id = "getCustomer",
    summary = "One customer.",
    params(("customer_id" = crate::domain::schema::Identifier, Path, description = "The customer's id.")),
    responses(
        (status = 200, description = "The customer.", body = Customer, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get_customer(
    State(state): State<AppState>,
    principal: Principal,
    Path(customer_id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    if check_str(&customer_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_customer(&customer_id));
    }
    state
        .store
        .customer(customer_id.clone())
        .await?
        .map(|c| tagged(StatusCode::OK, &etag(&c), c))
        .ok_or_else(|| unknown_customer(&customer_id))
}

/// `PUT /v1/sensors/{sensor_id}/item` (admin): what the sensor id is.
#[utoipa::path(
    put,
    path = "/v1/sensors/{sensor_id}/item",
    tag = "customers",
    operation_id = "putItem",
    summary = "Record the item behind a sensor id: manufacturer, model, serial number, customer (admin).",
    description = "May be recorded before the sensor is first calibrated (when the item \
        arrives). A customer named must exist (422 otherwise). Certificates print the \
        item and its customer.",
    params(super::openapi::SensorIdPath, super::openapi::ConditionalHeaders),
    request_body(content((ItemBody = "application/json",
        example = json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "QA-12345",
            "customer": "ACME"})))),
    responses(
        (status = 200, description = "Replaced.", body = Item, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 201, description = "Created.", body = Item, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        (status = 412, response = super::openapi::PreconditionFailed),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put_item(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&sensor_id, "sensor")?;
    let pre = precondition(&headers)?;
    let item = body
        .json::<ItemBody>()?
        .check(sensor_id, Timestamp::now())?;
    written(
        definitions::item(&state.lab, &principal, item, pre).await?,
        "item",
    )
}

/// `GET /v1/sensors/{sensor_id}/item`.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}/item",
    tag = "customers",
    operation_id = "getItem",
    summary = "The item behind a sensor id.",
    params(super::openapi::SensorIdPath),
    responses(
        (status = 200, description = "The item.", body = Item, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get_item(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let none = || {
        Problem::not_found(format!(
            "no item recorded for sensor `{}`",
            echo(&sensor_id)
        ))
    };
    if check_str(&sensor_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(none());
    }
    state
        .store
        .item(sensor_id.clone())
        .await?
        .map(|i| tagged(StatusCode::OK, &etag(&i), i))
        .ok_or_else(none)
}
