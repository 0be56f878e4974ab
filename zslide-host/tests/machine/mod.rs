//! A simulated machine (`host-sim serve`) in a thread of the test, on a
//! Unix socket under target/, stopped when dropped.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use host_sim::serve::{serve, Listener, Setup};

pub struct Machine {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
    pub addr: String,
}

impl Machine {
    pub fn start(name: &str, setup: Setup) -> Self {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");
        std::fs::create_dir_all(&dir).unwrap();
        let sock = dir.join(format!("{name}.sock"));
        let listener = Listener::bind(&format!("unix:{}", sock.display())).unwrap();
        let addr = listener.address();
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        // The machine's world is built on this thread's stack (a board's
        // worth of firmware state): more than a test thread's default.
        let thread = std::thread::Builder::new()
            .name(format!("machine {name}"))
            .stack_size(64 << 20)
            .spawn(move || {
                serve(&setup, &listener, &s).unwrap();
            })
            .unwrap();
        Machine {
            stop,
            thread: Some(thread),
            addr,
        }
    }
}

impl Drop for Machine {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
