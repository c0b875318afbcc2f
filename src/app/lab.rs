//! The laboratory an act works in: its records (the store), its compute
//! pool for CPU-heavy work, and the settings acts decide by. Built once at
//! start and shared by every transport.

use std::sync::Arc;
use std::time::Duration;

use tokio::sync::Semaphore;

use super::Error;
use crate::domain::review::Basis;
use crate::store::Store;

/// Inputs whose evaluation runs on the async worker (see
/// [`Lab::compute_for`]): the paper's six-run submission is 1.3 KiB.
pub const INLINE_BYTES: usize = 8 * 1024;

/// What every act works with.
#[derive(Clone)]
pub struct Lab {
    /// The records.
    pub store: Arc<dyn Store>,
    /// Permits for CPU-heavy work on the blocking pool.
    pub compute: Arc<Semaphore>,
    /// Which earlier calibration a new one is found against (as found).
    pub basis: Basis,
    /// How long an act may take before its caller gives up: an idempotency
    /// key's lease outlasts it.
    pub deadline: Duration,
}

impl Lab {
    /// The laboratory of a command run beside (or instead of) the service,
    /// over `store`: one compute permit, the default basis, a minute's
    /// deadline.
    pub fn offline(store: Arc<dyn Store>) -> Lab {
        Lab {
            store,
            compute: Arc::new(Semaphore::new(1)),
            basis: Basis::default(),
            deadline: Duration::from_secs(60),
        }
    }

    /// Runs the work of an input of `bytes` bytes: on the async worker when
    /// it is at most [`INLINE_BYTES`] (a tumble test of that size is parsed,
    /// identified, fused and assessed in tens of microseconds, less than the
    /// hop to the blocking pool and back costs), else as [`Lab::compute`].
    pub async fn compute_for<T: Send + 'static>(
        &self,
        bytes: usize,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Error> {
        if bytes <= INLINE_BYTES {
            return Ok(work());
        }
        self.compute(work).await
    }

    /// Runs CPU-heavy work (parsing, calibrating a submission) on the
    /// blocking pool, at most as many at once as there are permits, so that
    /// the async workers stay free for health probes and reads.
    pub async fn compute<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Error> {
        let _permit = self
            .compute
            .clone()
            .acquire_owned()
            .await
            .map_err(|_| Error::Internal)?;
        tokio::task::spawn_blocking(work).await.map_err(|e| {
            tracing::error!(error = %e, "a computation failed");
            Error::Internal
        })
    }
}
