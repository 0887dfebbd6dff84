//! The measurement side of penumbra, apart from the renderer: image comparison
//! ([`compare`], [`metrics`]), convergence ladders and experiments ([`convergence`],
//! [`experiment`]), the validation study against Mitsuba ([`validation`]) and Mitsuba's own
//! regression suite ([`suite`]), the statistics
//! behind the tests ([`stats`], [`chi2`]), plots ([`plot`]), batches of rays cast and timed ([`rays`]) and the interactive comparison page
//! ([`report`]).

pub mod chi2;
pub mod compare;
pub mod convergence;
pub mod experiment;
pub mod metrics;
pub mod plot;
pub mod rays;
pub mod report;
pub mod stats;
pub mod suite;
pub mod validation;
