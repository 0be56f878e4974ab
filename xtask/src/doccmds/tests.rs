use super::*;

fn aliases() -> HashMap<String, Vec<String>> {
    let mut a = HashMap::new();
    let w = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
    a.insert("sim".to_string(), w("run --release -p host-sim -- cut"));
    a.insert("xtask".to_string(), w("run --quiet --package xtask --"));
    a.insert("fw".to_string(), w("build --release --bins"));
    a
}

fn problems(text: &str, origin: Origin) -> Vec<String> {
    check_one(
        &Shown {
            line: 1,
            text: text.to_string(),
            origin,
        },
        &aliases(),
    )
}

#[test]
fn the_sim_alias_followed_by_dashes_is_refused_and_without_them_passes() {
    let p = problems("cargo sim -- --controller legacy-analog", Origin::Block);
    assert_eq!(p.len(), 1, "{p:?}");
    assert!(
        p[0].starts_with("host-sim receives `cut -- --controller legacy-analog`"),
        "{p:?}"
    );
    assert_eq!(
        problems("cargo sim --controller legacy-analog", Origin::Block),
        Vec::<String>::new()
    );
}

#[test]
fn a_mistyped_flag_or_value_is_refused_by_each_programs_own_parser() {
    assert_eq!(
        problems("host-sim cut --holes plugged", Origin::Block).len(),
        1
    );
    assert_eq!(problems("host-sim cut --rpn 300", Origin::Block).len(), 1);
    assert_eq!(problems("zslide link stauts", Origin::Block).len(), 1);
    assert_eq!(
        problems("cargo xtask figures --chek", Origin::Block).len(),
        1
    );
    assert_eq!(
        problems(
            "cargo run --release -p host-sim -- response --loop digitl",
            Origin::Block
        )
        .len(),
        1
    );
    assert!(problems("host-sim cut --holes filled --rpm 360", Origin::Block).is_empty());
    assert!(problems("zslide link status", Origin::Block).is_empty());
    assert!(problems("cargo xtask figures --check --quick", Origin::Block).is_empty());
}

#[test]
fn cargo_run_without_dashes_and_cargo_test_with_two_filters_are_refused() {
    let p = problems("cargo run --release -p host-sim cut", Origin::Block);
    assert!(p[0].contains("after `--`"), "{p:?}");
    let p = problems(
        "cargo test -p host-sim --lib cut::gridcut cut::rectgrid",
        Origin::Cell,
    );
    assert!(p[0].contains("one name filter"), "{p:?}");
    assert!(problems("cargo test -p host-sim --lib -- a b", Origin::Cell).is_empty());
    assert!(problems("cargo test -p host-sim --test faults", Origin::Cell).is_empty());
}

#[test]
fn usage_notation_is_read_as_a_reader_reads_it() {
    // Optional words are parsed too; placeholders pass where a value goes.
    assert!(problems("cargo xtask fuzz --seconds N [--target T]", Origin::Cell).is_empty());
    assert_eq!(
        problems("cargo xtask fuzz --seconds N [--targit T]", Origin::Cell).len(),
        1
    );
    // Every alternative of a cell is a command of its own.
    assert!(problems("zslide link status\\|faults\\|arm", Origin::Cell).is_empty());
    let p = problems("zslide link status\\|fautls", Origin::Cell);
    assert_eq!(p.len(), 1, "{p:?}");
    assert!(p[0].contains("fautls"), "{p:?}");
    // `...` elides what follows.
    assert!(problems("zslide --connect unix:PATH ...", Origin::Cell).is_empty());
    assert_eq!(
        problems("zslide --connect unix:PATH", Origin::Cell).len(),
        1
    );
}

#[test]
fn shell_lines_split_into_commands_without_redirections_or_comments() {
    let c = simple_commands(
        "printf '1,2\\n' | host-sim zcmd --table t.zsct > out.csv 2>&1; L=x zslide link arm # go",
    );
    let w = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
    assert_eq!(
        c,
        vec![
            w("printf 1,2\\n"),
            w("host-sim zcmd --table t.zsct"),
            w("zslide link arm")
        ]
    );
    assert_eq!(
        simple_commands("{ printf '\\000'; cat fe.zspb; } > $C/x"),
        vec![w("printf \\000"), w("cat fe.zspb")]
    );
}

#[test]
fn blocks_cells_and_prose_give_their_commands_with_lines() {
    let doc = "text `cargo sim --rpm 360` here\n\
               | a | `zslide link status` |\n\
               ```sh\n\
               cargo xtask test \\\n  --fuzz-seconds 0\n\
               echo no\n\
               ```\n\
               ```text\n\
               host-sim cut output\n\
               ```\n\
               ```sh quick\n\
               host-sim coeffs\n\
               ```\n";
    let (s, q) = shown(doc);
    let got: Vec<(usize, &str, Origin)> = s
        .iter()
        .map(|s| (s.line, s.text.as_str(), s.origin))
        .collect();
    assert_eq!(
        got,
        vec![
            (1, "cargo sim --rpm 360", Origin::Prose),
            (2, "zslide link status", Origin::Cell),
            (4, "cargo xtask test    --fuzz-seconds 0", Origin::Block),
            (12, "host-sim coeffs", Origin::Block),
        ]
    );
    assert_eq!(
        q,
        vec![QuickBlock {
            line: 12,
            script: "host-sim coeffs\n".into()
        }]
    );
}

#[test]
fn prose_may_name_a_command_without_its_arguments_but_not_misspell_it() {
    assert!(problems("zslide table flash", Origin::Prose).is_empty());
    assert!(problems("host-sim faults --stall-sweep", Origin::Prose).is_empty());
    assert_eq!(problems("zslide table flash", Origin::Cell).len(), 1);
    assert_eq!(problems("zslide tabel flash", Origin::Prose).len(), 1);
    assert_eq!(
        problems("host-sim faults --stall-swep", Origin::Prose).len(),
        1
    );
}

#[test]
fn a_blocks_variables_are_substituted_before_parsing() {
    let (s, _) = shown("```sh\nP=\"--plant-gain-error -0.15\"\nhost-sim track $P\n```\n");
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].text, "host-sim track --plant-gain-error -0.15");
    assert!(check_one(&s[0], &aliases()).is_empty());
    let (s, _) = shown("```sh\nP=\"--plant-gain-eror -0.15\"\nhost-sim track $P\n```\n");
    assert_eq!(check_one(&s[0], &aliases()).len(), 1);
}
