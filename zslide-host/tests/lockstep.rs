//! Issue 33, finding 9: `zslide identify` against `host-sim serve
//! --lockstep` gives the same result however late the host's frames
//! arrive. The host reaches the machine through a relay that holds each
//! chunk of the host's bytes for a stated time before passing it on (a
//! slow or loaded host); the process file and the per-frequency CSV of a
//! run without the delay and of a run with it must be the same bytes.

use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::time::Duration;

mod in_cut;
mod machine;
mod phase;
use in_cut::{identify, test_dir, Run};

/// A relay on a Unix socket of its own to the machine at `to`, for one
/// host connection: the host's bytes held `delay` before they go on, the
/// machine's passed at once. Returns the address the host connects to.
fn delaying_relay(name: &str, to: &str, delay: Duration) -> String {
    let sock: PathBuf = test_dir().join(format!("{name}.sock"));
    let _ = std::fs::remove_file(&sock);
    let listener = UnixListener::bind(&sock).unwrap();
    let machine = to.strip_prefix("unix:").unwrap().to_owned();
    std::thread::spawn(move || {
        let (mut host, _) = listener.accept().unwrap();
        let mut to_machine = UnixStream::connect(&machine).unwrap();
        let (mut from_machine, mut to_host) =
            (to_machine.try_clone().unwrap(), host.try_clone().unwrap());
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n @ 1..) = from_machine.read(&mut buf) {
                if to_host.write_all(&buf[..n]).is_err() {
                    break;
                }
            }
        });
        let mut buf = [0u8; 4096];
        while let Ok(n @ 1..) = host.read(&mut buf) {
            std::thread::sleep(delay);
            if to_machine.write_all(&buf[..n]).is_err() {
                break;
            }
        }
    });
    format!("unix:{}", sock.display())
}

fn run_with_delay(lockstep: bool, delay_ms: u64) -> in_cut::Identified {
    let name = format!("lockstep-{lockstep}-delay{delay_ms}");
    let relay = format!("{name}-relay");
    identify(&Run {
        name: &name,
        ke_scale: 1.0,
        seed: None,
        lockstep,
        repeats: Some(4),
        route: &|addr| delaying_relay(&relay, addr, Duration::from_millis(delay_ms)),
    })
}

/// Each frame held 0 ms in one run and 3 ms in the other (at 1 ms of
/// machine time per link poll, three polls' worth: a real-time machine
/// would run 60 loop ticks further between any two of the host's frames).
#[test]
fn identify_in_lockstep_is_bit_identical_whatever_the_hosts_delays() {
    let prompt = run_with_delay(true, 0);
    let slow = run_with_delay(true, 3);
    eprintln!("{}", prompt.report);
    assert!(
        prompt.process_file == slow.process_file && prompt.csv == slow.csv,
        "prompt host: {} ± {} lbf/in; slow host: {} ± {} lbf/in",
        prompt.process.stiffness_lbf_per_in,
        prompt.process.stiffness_sigma,
        slow.process.stiffness_lbf_per_in,
        slow.process.stiffness_sigma
    );
}

/// The defect the lockstep removes, shown (not in the suite: its outcome
/// rests on the wall clock): the same two runs against the machine served
/// in real time differ, because the ticks the host's requests land on,
/// and so the machine's state and noise in the windows, follow the host's
/// timing. `cargo test --release -p zslide-host --test lockstep --
/// --ignored`.
#[test]
#[ignore]
fn identify_in_real_time_depends_on_the_hosts_delays() {
    let prompt = run_with_delay(false, 0);
    let slow = run_with_delay(false, 3);
    eprintln!(
        "prompt host: {} ± {} lbf/in; slow host: {} ± {} lbf/in",
        prompt.process.stiffness_lbf_per_in,
        prompt.process.stiffness_sigma,
        slow.process.stiffness_lbf_per_in,
        slow.process.stiffness_sigma
    );
    assert!(prompt.process_file != slow.process_file || prompt.csv != slow.csv);
}
