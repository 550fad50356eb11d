//! The offline baker: infers layered environment maps so that the hardware rendering matches the
//! reference ray tracer (hybrid-rendering paper §4.2–4.3). It grows with the baker issue.
