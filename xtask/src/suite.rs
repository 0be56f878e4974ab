//! `cargo xtask test`: everything CI runs, with one tally at the end.

use std::time::Instant;

use crate::images::{build_board, build_qemu};
use crate::qemu::run_qemu;
use crate::size::print_sizes;
use crate::tools::{ensure, Tool};
use crate::{
    cycles, faultpath, figures, fuzz, link, nextest, nopanic, nucleo, powercut, replay, root,
    snapshot, step, table_checks, target_dir, trace, watchdog, Result,
};

pub fn run(fuzz_seconds: u32) -> Result<u8> {
    let started = Instant::now();
    let mut missing = ensure(&[
        Tool::Target,
        Tool::FlipLink,
        Tool::Qemu,
        Tool::DefmtPrint,
        Tool::Viewers,
    ]);
    let viewers = !missing
        .iter()
        .any(|m| m.starts_with("vcd2fst") || m.starts_with("sigrok"));
    let firmware_possible = !missing.iter().any(|m| {
        m.starts_with("Rust target") || m.starts_with("rustup") || m.starts_with("flip-link")
    });
    let qemu_possible = firmware_possible
        && !missing
            .iter()
            .any(|m| m.starts_with("qemu") || m.starts_with("defmt-print"));

    step("import cycles between modules (every crate)");
    let modules = cycles::check_crates(&root(), cycles::CRATES)?;
    modules.print();

    let results = nextest::host_tests()?;
    // The docs' cheap figures (the full set: `cargo xtask figures --check`),
    // their generated sections, cited names and shown commands: each figure
    // counts as a test, and the other checks as one test together.
    let (figure_count, drift) = figures::figures(true, true)?;
    let (doc_summary, doc_problems) = figures::doc_checks(true)?;
    for line in drift.iter().chain(&doc_problems) {
        eprintln!("{line}");
    }
    let docs_passed = (figure_count - drift.len()) as u64 + u64::from(doc_problems.is_empty());
    let docs_failed = drift.len() as u64 + u64::from(!doc_problems.is_empty());
    let docs_line = format!(
        "{figure_count} quick figures, {} drifted; {doc_summary}",
        drift.len()
    );

    if firmware_possible {
        build_board()?;
        build_qemu()?;
        print_sizes()?;
        nopanic::check_images()?;
    }
    let mut qemu_code = None;
    let mut replay_line = None;
    let mut watchdog_line = None;
    let mut vcd_line = None;
    let mut board_checks = 0u64;
    if qemu_possible {
        let (code, lines) = run_qemu()?;
        if code != 0 {
            return Err(format!("the QEMU image exited with status {code}"));
        }
        snapshot::check(&lines, false)?;
        qemu_code = Some(code);
        board_checks += u64::from(table_checks::qemu_table_checks(&lines)?);
        board_checks += u64::from(faultpath::params_check()?);
        board_checks += u64::from(link::end_to_end()?);
        eprintln!("QEMU power cuts: {}", powercut::check()?);
        board_checks += 1;
        replay_line = Some(replay::check()?);
        watchdog_line = Some(watchdog::check()?);
        eprintln!("QEMU fault paths: {}", faultpath::check()?);
        board_checks += 2;
        if viewers {
            let vcd = target_dir().join("qemu-trace/run.vcd");
            let (summary, t) = trace::qemu_vcd(&vcd)?;
            eprintln!("QEMU trace: {summary}");
            vcd_line = Some(trace::check_both(&vcd, t.runs[0])?);
            board_checks += 2;
        }
    }

    // The release zslide-fw ELF on the emulated NUCLEO (`nucleo.rs`).
    let mut nucleo_line = None;
    if firmware_possible {
        match nucleo::require_unicorn().and_then(|()| nucleo::build_emulator()) {
            Ok(()) => {
                board_checks += nucleo::model_tests()?;
                let r = nucleo::check(nucleo::TEST_MS)?;
                if !nucleo::report(&r) {
                    return Err(
                        "emulated NUCLEO: tracking outside its tolerance of the QEMU image's"
                            .into(),
                    );
                }
                board_checks += r["link_checks_passed"].as_u64().unwrap_or(0);
                nucleo_line = Some(format!(
                    "booted, armed, tracking {:.2} µin (QEMU {:.2}), {} of {} faults latched, {} checks, {:.0} ms of machine time",
                    r["tracking_max_uin"].as_f64().unwrap_or(0.0),
                    r["qemu_tracking_max_uin"].as_f64().unwrap_or(0.0),
                    r["faults_latched"],
                    r["faults_injected"],
                    r["link_checks_passed"],
                    r["machine_ms"].as_f64().unwrap_or(0.0)
                ));
            }
            Err(e) => missing.push(e),
        }
    }

    // A short fuzz run of every target: a finding fails the run (after the
    // summary), each clean target counts as one passed test.
    let mut fuzz_line = String::from("NOT RUN (--fuzz-seconds 0)");
    let (mut fuzz_passed, mut fuzz_failed) = (0u64, 0u64);
    if fuzz_seconds > 0 {
        let fuzz_missing = fuzz::missing_tools();
        if fuzz_missing.is_empty() {
            match fuzz::run_targets(&fuzz::TARGETS, fuzz_seconds) {
                Ok(runs) => {
                    fuzz_passed = runs.len() as u64;
                    let execs: u64 = runs.iter().map(|(_, s)| s.execs).sum();
                    fuzz_line = format!(
                        "{} targets × {fuzz_seconds} s, {execs} executions, no finding",
                        runs.len()
                    );
                }
                Err(e) => {
                    fuzz_failed = e.lines().skip(1).count().max(1) as u64;
                    fuzz_passed = (fuzz::TARGETS.len() as u64).saturating_sub(fuzz_failed);
                    fuzz_line = format!("FAILED: {e}");
                }
            }
        } else {
            fuzz_line = "NOT RUN (tools missing, below)".into();
            missing.extend(fuzz_missing);
        }
    }

    eprintln!("\n==> summary ({:.0} s)", started.elapsed().as_secs_f64());
    let (passed, failed, ignored) = results;
    eprintln!("host tests: passed ({passed} passed, {failed} failed, {ignored} ignored)");
    eprintln!(
        "board firmware: {}",
        if firmware_possible {
            "built"
        } else {
            "NOT BUILT"
        }
    );
    if firmware_possible {
        eprintln!("panic paths from interrupt handlers: none (every image)");
    }
    eprintln!(
        "QEMU image: {}",
        match qemu_code {
            Some(_) => "ran, exit status 0, log as expected",
            None => "NOT RUN",
        }
    );
    if qemu_code.is_some() {
        eprintln!("QEMU table region and host link end to end: {board_checks} checks passed");
    }
    eprintln!(
        "QEMU replay: {}",
        replay_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "QEMU watchdog: {}",
        watchdog_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "VCD (the traced QEMU run, PASS; a host-sim machine VCD): {}",
        vcd_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "emulated NUCLEO (release zslide-fw): {}",
        nucleo_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!("fuzz: {fuzz_line}");
    eprintln!("docs: {docs_line}");
    eprintln!("{}", modules.summary());
    eprintln!("{}", modules.biggest_line());
    // The cycle check is one test of the tally.
    let cycle_failed = u64::from(!modules.cycles.is_empty());
    let code = if fuzz_failed > 0 || cycle_failed > 0 || docs_failed > 0 {
        1
    } else if missing.is_empty() {
        0
    } else {
        eprintln!("incomplete: missing, and could not be installed:");
        for m in &missing {
            eprintln!("  - {m}");
        }
        1
    };
    // The last line is the plain "N passed, N failed" tally CI reads; the
    // last libtest line above is a doc-test run that may count zero.
    eprintln!(
        "tests: {} passed, {} failed, {ignored} skipped",
        passed + fuzz_passed + board_checks + (1 - cycle_failed) + docs_passed,
        failed + fuzz_failed + cycle_failed + docs_failed
    );
    Ok(code)
}
