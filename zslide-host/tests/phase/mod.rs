//! Waiting for the served machine's loop to reach a phase, with a
//! deadline (a test must fail, not hang).

use std::time::{Duration, Instant};

use zslide::link::proto::LoopPhase;
use zslide_host::client::Link;

pub fn wait_phase(link: &mut Link, want: LoopPhase) {
    let start = Instant::now();
    loop {
        let s = link.client().unwrap().status().unwrap();
        if s.state.phase == want {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "not {want:?} within 30 s: {}",
            zslide_host::words::status_text(&s)
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}
