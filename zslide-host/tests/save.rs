//! `zslide params save` against `host-sim serve`: the parameters in force
//! go to the machine's parameter store, and the machine served again on
//! the same flash (a power cycle) boots with them; a save while armed is
//! refused and writes nothing.

use std::time::{Duration, Instant};

use host_sim::serve::Setup;
use zslide::link::proto::LoopPhase;
use zslide_host::cli::run_line;
use zslide_host::client::Link;

mod machine;
use machine::Machine;

fn wait_phase(link: &mut Link, want: LoopPhase) {
    let start = Instant::now();
    while link.client().unwrap().status().unwrap().state.phase != want {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "not {want:?} within 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_saved_parameter_survives_a_restart_and_a_save_while_armed_is_refused() {
    let setup = Setup::new(host_sim::scenario::load("legacy-hw").unwrap());
    let flash_before = setup.params_flash.lock().unwrap().bytes.to_vec();
    {
        let m = Machine::start("save-1", setup.clone());
        let mut link = Link::new(&m.addr, Duration::from_secs(10));
        let built_in = run_line(&mut link, "params get following_error_ms").unwrap();
        assert!(!built_in.contains("= 3 ms"), "{built_in}");
        run_line(&mut link, "params set following_error_ms 3").unwrap();
        let saved = run_line(&mut link, "params save").unwrap();
        assert!(
            saved.starts_with(&format!(
                "saved {} parameters to the machine's parameter store",
                zslide::params::PARAMS.len()
            )),
            "{saved}"
        );
        // The status names the block just saved, not the boot's source;
        // after a second save, the second block's CRC.
        let crc = |said: &str| said.split("block CRC ").nth(1).unwrap()[..10].to_string();
        let status = run_line(&mut link, "link status").unwrap();
        assert!(status.contains(&format!("CRC {}", crc(&saved))), "{status}");
        assert!(!status.contains("built-in"), "{status}");
        run_line(&mut link, "params set following_error_ms 3.5").unwrap();
        let second = run_line(&mut link, "params save").unwrap();
        assert_ne!(crc(&second), crc(&saved));
        let status = run_line(&mut link, "link status").unwrap();
        assert!(
            status.contains(&format!("CRC {}", crc(&second))),
            "{status}"
        );
        run_line(&mut link, "params set following_error_ms 3").unwrap();
        run_line(&mut link, "params save").unwrap();

        // Armed: refused by name; the store keeps the block saved above.
        run_line(&mut link, "params set following_error_ms 4").unwrap();
        assert!(run_line(&mut link, "link arm")
            .unwrap()
            .contains("loop armed"));
        wait_phase(&mut link, LoopPhase::Engaged);
        let e = run_line(&mut link, "params save").unwrap_err();
        assert!(e.contains("saved only while the loop is disarmed"), "{e}");
    }
    let flash_after = setup.params_flash.lock().unwrap().bytes.to_vec();
    let written = flash_after
        .iter()
        .zip(&flash_before)
        .filter(|(a, b)| a != b)
        .count();
    assert!(written > 0, "the save wrote nothing to the flash");

    // Served again on the same flash: the boot reads the store.
    let m = Machine::start("save-2", setup.clone());
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let got = run_line(&mut link, "params get following_error_ms").unwrap();
    assert!(got.contains("following_error_ms = 3 ms"), "{got}");
    let status = run_line(&mut link, "link status").unwrap();
    assert!(
        status.contains(&format!(
            "parameter block of {} entries",
            zslide::params::PARAMS.len()
        )),
        "{status}"
    );
}

/// `host-sim serve --params-flash FILE`: the region's image outlives the
/// simulator process, as the board's flash outlives a power cycle; a file
/// that is not a whole region is refused by name, not served as erased.
#[test]
fn a_saved_parameter_survives_a_new_simulator_through_its_params_flash_file() {
    let dir =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("params-flash.bin");
    let _ = std::fs::remove_file(&file);
    let legacy = || host_sim::scenario::load("legacy-hw").unwrap();
    {
        let setup = Setup::new(legacy()).with_params_file(file.clone()).unwrap();
        let m = Machine::start("save-file-1", setup);
        let mut link = Link::new(&m.addr, Duration::from_secs(10));
        run_line(&mut link, "params set following_error_ms 3").unwrap();
        run_line(&mut link, "params save").unwrap();
    }
    let image = std::fs::read(&file).unwrap();
    assert_eq!(
        image.len(),
        256 * 1024,
        "the image is the NUCLEO's 256 KiB region"
    );

    // A new setup, nothing shared with the first but the file.
    let setup = Setup::new(legacy()).with_params_file(file.clone()).unwrap();
    let m = Machine::start("save-file-2", setup);
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let got = run_line(&mut link, "params get following_error_ms").unwrap();
    assert!(got.contains("following_error_ms = 3 ms"), "{got}");

    let short = dir.join("params-flash-short.bin");
    std::fs::write(&short, [0xFFu8; 100]).unwrap();
    let e = Setup::new(legacy())
        .with_params_file(short.clone())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("params-flash-short.bin: 100 bytes, but a parameter region image is 262144"),
        "{e}"
    );
}
