//! Customers, and the items behind sensor ids, stored as their JSON
//! definitions.

use async_trait::async_trait;

use super::SqliteStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::customers::{Customer, Item};
use crate::store::conditional::{Precondition, Put};
use crate::store::{Customers, StoreError};

const CUSTOMERS: Table = Table {
    name: "customers",
    key: "customer_id",
    what: "a customer",
    kind: "customer",
    object: "customers/",
};

const ITEMS: Table = Table {
    name: "items",
    key: "sensor_id",
    what: "an item",
    kind: "item",
    object: "items/",
};

#[async_trait]
impl Customers for SqliteStore {
    async fn put_customer(
        &self,
        c: Customer,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Customer>, StoreError> {
        self.write("put_customer", move |conn| {
            let id = c.customer_id.clone();
            let put = definitions::put(conn, &CUSTOMERS, &id, |_| c, &pre, by)?;
            let commit = matches!(put, Put::Written { .. });
            Ok((put, commit))
        })
        .await
    }

    async fn customer(&self, customer_id: String) -> Result<Option<Customer>, StoreError> {
        self.run("customer", move |conn| {
            definitions::one(conn, &CUSTOMERS, &customer_id)
        })
        .await
    }

    async fn customers(&self) -> Result<Vec<Customer>, StoreError> {
        self.run("customers", |conn| definitions::all(conn, &CUSTOMERS))
            .await
    }

    async fn put_item(
        &self,
        i: Item,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Item>, StoreError> {
        self.write("put_item", move |conn| {
            let id = i.sensor_id.clone();
            let put = definitions::put(conn, &ITEMS, &id, |_| i, &pre, by)?;
            let commit = matches!(put, Put::Written { .. });
            Ok((put, commit))
        })
        .await
    }

    async fn item(&self, sensor_id: String) -> Result<Option<Item>, StoreError> {
        self.run("item", move |conn| {
            definitions::one(conn, &ITEMS, &sensor_id)
        })
        .await
    }

    async fn items(&self) -> Result<Vec<Item>, StoreError> {
        self.run("items", |conn| definitions::all(conn, &ITEMS))
            .await
    }
}
