//! The kinds of calibration as the documents read them: each kind's module
//! turns its stored result document into a [`Document`] — its quantities
//! and the few passages only it writes — over which the certificate and the
//! DCC are written once, and into a [`Page`], its sections of the one
//! calibration page. A new kind is a module here and a variant of
//! [`StoredDoc`].

pub mod single_axis;
pub mod thermal;
pub mod triad;

use super::certificate::Context;
use super::document::{Document, Page};
use super::stored::StoredDoc;

/// Stored calibration `d` as its documents read it, in context `c`.
pub fn document<'a>(d: &'a StoredDoc, c: &Context) -> Document<'a> {
    match d {
        StoredDoc::Axis(d) => single_axis::document(d, c),
        StoredDoc::Triad(d) => triad::document(d, c),
        StoredDoc::Thermal(d) => thermal::document(d, c),
        StoredDoc::ThermalTriad(d) => thermal::triad::document(d, c),
    }
}

/// Stored calibration `d` as its page shows it.
pub fn page(d: &StoredDoc) -> Page<'_> {
    match d {
        StoredDoc::Axis(d) => single_axis::page::page(d),
        StoredDoc::Triad(d) => triad::page::page(d),
        StoredDoc::Thermal(d) => thermal::page::page(d),
        StoredDoc::ThermalTriad(d) => thermal::triad::page(d),
    }
}
