//! Clouds larger than memory: conversion to COPC and view-dependent streaming of a COPC
//! octree from a local file or an HTTP server.

pub mod convert;
pub mod copc_write;
pub mod loader;
pub mod records;
pub mod select;
pub mod tiles;
pub mod vpc;
