//! API tests over real HTTP against a server bound to a free port.

mod endpoints;
mod errors;
mod helpers;
mod paper;
mod restart;
