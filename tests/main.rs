//! The end-to-end tests of postflight, one module per stage or format, in
//! one test binary: the workspace's dependencies link once rather than per
//! file, and the harness shares both cores across every test instead of
//! running the files one after another.

mod common;

mod architecture;
mod batch;
mod compare;
mod coverage;
mod detect;
mod geodesy;
mod gtsp;
mod ingest;
mod localise;
mod octomap;
mod parsers;
mod photos;
mod pipeline;
mod record;
mod recordings;
mod replan;
mod review;
mod simulate;
