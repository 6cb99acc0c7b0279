//! The server in-process on a free localhost port, through real HTTP requests.

mod admission;
mod common;
mod edges;
mod routes;
