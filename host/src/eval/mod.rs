//! Scoring, pure: the UOIS metrics ([`metrics`]: overlap and boundary P/R/F with Hungarian
//! matching) and the motion ceiling ([`ceiling`]: the best mask motion could reveal, that
//! RISeg is judged against).

pub mod ceiling;
pub mod metrics;
