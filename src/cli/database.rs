//! The commands that open the database themselves, the service stopped or
//! not: `migrate` (a copy between engines), `audit verify` and
//! `audit adopt`.

use std::path::Path;
use std::process::ExitCode;

use crate::domain::timestamp::Timestamp;

use super::out;

/// A SQLite database named by `database` must exist unless `create`
/// (PostgreSQL databases are created by their server's administrator).
pub(super) fn existing(database: &str, create: bool) -> anyhow::Result<()> {
    if create || database.starts_with("postgres://") || database.starts_with("postgresql://") {
        return Ok(());
    }
    let path = database
        .strip_prefix("sqlite://")
        .or_else(|| database.strip_prefix("sqlite:"))
        .unwrap_or(database);
    if Path::new(path).exists() {
        return Ok(());
    }
    let cwd = std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string());
    anyhow::bail!(
        "no database at {path} (in {cwd}); point --database (ACCELCAL_DATABASE_URL) at the \
         service's database, or pass --create to make a new one"
    )
}

pub(super) async fn migrate(
    from: String,
    to: String,
    into_non_empty: bool,
) -> anyhow::Result<ExitCode> {
    use anyhow::Context;
    existing(&from, false).context("--from")?;
    let source = crate::store::open(&from)
        .await
        .with_context(|| format!("opening {from}"))?;
    let target = crate::store::open(&to)
        .await
        .with_context(|| format!("opening {to}"))?;
    // Named without credentials: the description is stored in the target.
    let described = match from.split_once("://") {
        Some((scheme, rest)) => format!("{scheme}://{}", rest.rsplit('@').next().unwrap_or(rest)),
        None => from.clone(),
    };
    let copied = crate::store::copy::copy(
        source.as_ref(),
        &described,
        target.as_ref(),
        into_non_empty,
        Timestamp::now(),
    )
    .await;
    source.close().await;
    target.close().await;
    match copied {
        Ok(c) => Ok(out(&serde_json::to_string_pretty(&c)?)),
        Err(e) => {
            eprintln!("accelcal: {e}");
            Ok(ExitCode::FAILURE)
        }
    }
}

pub(super) async fn verify_audit(database: String) -> anyhow::Result<ExitCode> {
    use anyhow::Context;
    existing(&database, false)?;
    let store = crate::store::open(&database)
        .await
        .with_context(|| format!("opening {database}"))?;
    let verified = crate::store::audit::verify(store.as_ref()).await;
    store.close().await;
    match verified {
        Ok(v) => Ok(out(&serde_json::to_string_pretty(&v)?)),
        Err(e) => {
            eprintln!("accelcal: the audit trail does not verify: {e}");
            Ok(ExitCode::FAILURE)
        }
    }
}

pub(super) async fn adopt_audit(database: String) -> anyhow::Result<ExitCode> {
    use anyhow::Context;
    existing(&database, false)?;
    let store = crate::store::open(&database)
        .await
        .with_context(|| format!("opening {database}"))?;
    let adoption =
        crate::store::verify::adoption(store.as_ref(), crate::domain::audit::Actor::command_line())
            .await;
    let out_code = match adoption {
        Ok(events) => {
            let objects: Vec<&str> = events.iter().map(|e| e.object.as_str()).collect();
            let report = serde_json::json!({"adopted": objects.len(), "objects": objects});
            let printed = serde_json::to_string_pretty(&report)?;
            store.record(events).await?;
            out(&printed)
        }
        Err(e) => {
            eprintln!("accelcal: nothing adopted: {e}");
            ExitCode::FAILURE
        }
    };
    store.close().await;
    Ok(out_code)
}
