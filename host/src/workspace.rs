//! `Vec`-backed scratch for riseg-core's caller-provided buffers.
