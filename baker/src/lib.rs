//! The offline baker: infers layered environment maps so that the hardware rendering matches the
//! reference ray tracer (hybrid-rendering paper §4.2–4.3). So far it places the layer shells
//! ([`clustering`]); the targets, rendering matrices and solver come with the baker issue.

pub mod clustering;
