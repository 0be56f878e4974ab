use super::*;

fn err(text: &str) -> String {
    Config::from_toml(text)
        .and_then(|c| c.to_spec().map_err(anyhow::Error::from))
        .unwrap_err()
        .to_string()
}

#[test]
fn empty_file_is_the_dissertation() {
    let s = Config::from_toml("").unwrap().to_spec().unwrap();
    assert_eq!(s, TableSpec::dissertation());
    let f = Config::from_toml("[surface]\nfocal_length_in = 79.175\n")
        .unwrap()
        .to_spec()
        .unwrap();
    assert!((f.surface.c() - 316.7).abs() < 1e-12);
    let p = Config::from_toml("[surface]\ncompensation = \"profile-normal\"\n")
        .unwrap()
        .to_spec()
        .unwrap();
    assert_eq!(p.surface.compensation(), Compensation::ProfileNormal);
    assert!(Config::from_toml("[surface]\ncompensation = \"exact\"\n").is_err());
}

#[test]
fn invalid_fields_are_named_with_their_limit() {
    for (text, starts) in [
        ("[surface]\nc_in = 0.0", "surface.c_in"),
        ("[surface]\nc_in = -316.7", "surface.c_in"),
        ("[surface]\nc_in = nan", "surface.c_in"),
        (
            "[surface]\nfocal_length_in = -1.0",
            "surface.focal_length_in",
        ),
        (
            "[surface]\nc_in = 316.7\nfocal_length_in = 79.0",
            "surface.focal_length_in",
        ),
        ("[surface]\ns_y_in = 0.0", "surface.s_y_in"),
        (
            "[surface]\ntool_radius_in = -0.125",
            "surface.tool_radius_in",
        ),
        ("[grid]\nstep_in = 0.0", "grid.step_in"),
        ("[grid]\nstep_in = -0.1", "grid.step_in"),
        ("[grid]\nstep_in = 0.3", "grid.step_in"),
        ("[grid]\nx_min_in = -1.0", "grid.x_min_in"),
        ("[grid]\nx_max_in = inf", "grid.x_max_in"),
        ("[grid]\nx_max_in = 70.0\nx_null_in = 7.2", "grid.x_max_in"),
        ("[grid]\nx_null_in = 9.0", "grid.x_null_in"),
        ("[series]\nterms = 0", "series.terms"),
        ("[series]\nterms = 32", "series.terms"),
        (
            "[series]\nrepresentation = \"harmonic\"\nterms = 16",
            "series.terms",
        ),
        ("[format]\ncoeff_frac_bits = 40", "format.coeff_frac_bits"),
    ] {
        let e = err(text);
        assert!(e.starts_with(starts), "{text:?} gave {e:?}");
    }
    // The domain message carries the limit.
    let e = err("[grid]\nx_max_in = 70.0\nstep_in = 0.5\nx_null_in = 7.0");
    assert!(
        e.contains("defined for X <= 5") && e.contains(" in at this geometry"),
        "{e}"
    );
    let e = err("[grid]\nstep_in = 0.3");
    assert!(e.contains("whole steps"), "{e}");
    // Misspelt keys are refused, not defaulted.
    assert!(err("[grid]\nstep = 0.1").contains("unknown field"));
}

/// Found by the geometry fuzz target: a deep paraboloid (f = 5 in) needs
/// coefficients beyond the firmware's ±1/8 in; clamped, the command
/// was +331 µin at X = 6.9 in, and the firmware's load check refused
/// the table. The generator refuses it instead, naming the field;
/// likewise a quantisation too coarse for a command that is never
/// positive.
#[test]
fn tables_the_firmware_would_refuse_are_refused_by_name() {
    let gen = |text: &str| {
        crate::coeffgen::generate(&Config::from_toml(text).unwrap().to_spec().unwrap())
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    let e = gen("[surface]\nfocal_length_in = 5\n").unwrap_err();
    assert!(
        e.starts_with("grid.x_max_in = 8: at X = ")
            && e.contains("beyond the firmware's ±0.125 in"),
        "{e}"
    );
    gen("[surface]\nfocal_length_in = 5\n[grid]\nx_max_in = 2.0\nx_null_in = 2.0\n").unwrap();
    let e = gen("[format]\ncoeff_frac_bits = 10\n[series]\nrepresentation = \"harmonic\"\n")
        .unwrap_err();
    assert!(
        e.starts_with("format.coeff_frac_bits = 10: quantised coefficients give Z = +"),
        "{e}"
    );
    gen("").unwrap();
    gen("[format]\ncoeff_frac_bits = 28\n").unwrap();
}
