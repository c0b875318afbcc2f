//! The application layer: the laboratory's acts — identifying (a kind's
//! assessment without an id: nothing stored), submitting, reviewing
//! (approving, rejecting, withdrawing, disposing of a hold), superseding,
//! reprocessing, identifying coefficients over temperature ([`thermal`]),
//! holding for a standard's nonconformity, recording a sensor
//! type, standard, customer or item, issuing and revoking tokens — each a
//! function over the store and the domain that takes typed input and a
//! principal and returns a typed outcome or an [`Error`], with no HTTP in
//! it. The HTTP handlers parse, authenticate, call one act and render; the
//! command line and background work call the same acts.
//!
//! What differs between kinds of calibration (single-axis, triad) is how a
//! submission is read and assessed: [`single_axis`] and [`triad`], each
//! answering an [`Assessed`] that the acts store alike, chosen in one place
//! ([`Kind`]).

pub mod clock;
pub mod definitions;
pub mod delivery;
mod error;
pub mod events;
pub mod hold;
pub mod kind;
mod lab;
pub mod review;
pub mod single_axis;
pub mod standards;
pub mod subject;
pub mod submit;
pub mod supersede;
pub mod thermal;
pub mod tokens;
pub mod triad;
mod upload;
pub mod webhooks;

pub use error::Error;
pub use kind::Kind;
pub use lab::{INLINE_BYTES, Lab};
pub use submit::{Assessed, Submitted};
pub use upload::Upload;
