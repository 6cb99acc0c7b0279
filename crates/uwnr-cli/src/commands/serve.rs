//! `uwnr serve`: the local comparison page (library: `uwnr_serve`).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_serve::{ServeConfig, Server};

use crate::cli::ServeArgs;

pub fn run(a: &ServeArgs) -> Result<ExitCode> {
    let mut config = ServeConfig::new(a.clean.clone(), a.references.clone());
    config.host = a.host;
    config.port = a.port;
    config.preview_size = a.preview_size;
    config.max_upload_bytes = a.max_upload_mb.saturating_mul(1024 * 1024);
    config.max_pixels = a.max_pixels;
    config.max_dimension = a.max_dimension;
    config.queue = a.queue;
    config.memory_bytes = a.memory_mb.saturating_mul(1024 * 1024);
    config.allowed_hosts.clone_from(&a.allow_host);
    if let Some(w) = a.workers {
        config.workers = w;
    }
    if !a.host.is_loopback() {
        eprintln!(
            "warning: listening on {}: anyone on the network who has the address printed below \
             (it carries a token) can see the page and the images in {} and {}",
            a.host,
            a.clean.display(),
            a.references.display()
        );
    }
    eprintln!("loading the methods...");
    let server = Server::start(config).context("starting the server")?;
    let (cleans, refs) = server.engine().libraries();
    eprintln!(
        "{} clean image(s) in {}, {} reference(s) in {}",
        cleans.len(),
        cleans.dir().display(),
        refs.len(),
        refs.dir().display()
    );
    if a.host.is_unspecified() {
        eprintln!(
            "listening on all interfaces: the address below is this machine's loopback; from \
             another machine, put this machine's name or address in its place"
        );
    }
    // The address on stdout, alone on its line, for scripts and tests to read.
    println!("serving on {}", server.url());
    // Ctrl-C, SIGTERM and SIGHUP end the process without running destructors: remove the
    // dropped images first, after the one being written (if any) and before any other.
    let engine = server.shared_engine();
    ctrlc::set_handler(move || {
        let _ = engine.remove_uploads();
        std::process::exit(130);
    })
    .context("installing the Ctrl-C handler")?;
    eprintln!("press Ctrl-C to stop");
    server.wait();
    Ok(ExitCode::SUCCESS)
}
