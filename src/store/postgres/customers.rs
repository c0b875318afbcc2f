//! Customers, and the items behind sensor ids, stored as their JSON
//! definitions.

use async_trait::async_trait;

use super::PostgresStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::customers::{Customer, Item};
use crate::store::conditional::{Precondition, Put};
use crate::store::{Customers, StoreError};

const CUSTOMERS: Table = Table {
    name: "customers",
    key: "customer_id",
    kind: "customer",
    object: "customers/",
};

const ITEMS: Table = Table {
    name: "items",
    key: "sensor_id",
    kind: "item",
    object: "items/",
};

#[async_trait]
impl Customers for PostgresStore {
    async fn put_customer(
        &self,
        c: Customer,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Customer>, StoreError> {
        act!(self, "put_customer", |client| {
            let id = c.customer_id.clone();
            definitions::put(&mut client, &CUSTOMERS, &id, |_| c, &pre, by).await
        })
    }

    async fn customer(&self, customer_id: String) -> Result<Option<Customer>, StoreError> {
        op!(self, "customer", |client| {
            definitions::one(&client, &CUSTOMERS, &customer_id).await
        })
    }

    async fn customers(&self) -> Result<Vec<Customer>, StoreError> {
        op!(self, "customers", |client| {
            definitions::all(&client, &CUSTOMERS).await
        })
    }

    async fn put_item(
        &self,
        i: Item,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Item>, StoreError> {
        act!(self, "put_item", |client| {
            let id = i.sensor_id.clone();
            definitions::put(&mut client, &ITEMS, &id, |_| i, &pre, by).await
        })
    }

    async fn item(&self, sensor_id: String) -> Result<Option<Item>, StoreError> {
        op!(self, "item", |client| {
            definitions::one(&client, &ITEMS, &sensor_id).await
        })
    }

    async fn items(&self) -> Result<Vec<Item>, StoreError> {
        op!(self, "items", |client| definitions::all(&client, &ITEMS)
            .await)
    }
}
