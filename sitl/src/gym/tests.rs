//! Tests of the environment core.
