//! The pages a newcomer reads say what is: every command in a shell block of the README and
//! of `docs/*.md` names files, configs, packages, benches and examples that exist and flags its
//! program accepts; the quick ones (`validate`, `analyze`, the quick plans) run as written and
//! give the status they should; the long ones (`run`, `render`, `monitor`) take a config that
//! validates and that a test runs, with flags a test uses; and every relative link of the
//! project's Markdown pages points at a file, and a heading, that exist.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "a test, bench or example: a panic is its failure, with the message it gives"
)]

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use common::{icrflow, root, scratch};

/// The pages whose commands are checked: the README and every page of `docs/`.
fn command_pages() -> Vec<PathBuf> {
    let mut pages = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

/// The pages whose links are checked: the command pages, the top-level pages and every
/// directory's README (one level down, and `tests/bad_input/`).
fn link_pages() -> Vec<PathBuf> {
    let mut pages = command_pages();
    for name in [
        "ARCHITECTURE.md",
        "BENCHMARKS.md",
        "tests/bad_input/README.md",
    ] {
        pages.push(root().join(name));
    }
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with('.') || name == "target" || name == "out" {
            continue;
        }
        if dir.join("README.md").is_file() {
            pages.push(dir.join("README.md"));
        }
    }
    pages
}

/// A page's path from the repository root, for messages.
fn shown(page: &Path) -> String {
    page.strip_prefix(root())
        .unwrap_or(page)
        .display()
        .to_string()
}

// ---------------------------------------------------------------------------------------
// Reading commands out of Markdown

/// One command of a shell block: its page, its line and its words (quotes removed,
/// environment assignments and wrappers such as `sudo` and `time` taken off the front).
#[derive(Debug, Clone)]
struct Cmd {
    page: String,
    line: usize,
    words: Vec<String>,
}

impl Cmd {
    fn at(&self) -> String {
        format!("{}:{}: `{}`", self.page, self.line, self.words.join(" "))
    }
}

/// The fenced blocks of `text` whose info string is a shell's, each with the line of its
/// first content line.
fn shell_blocks(text: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    let mut open: Option<(usize, bool, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(info) = trimmed.strip_prefix("```") {
            match open.take() {
                None => {
                    let shell = matches!(info.trim(), "sh" | "bash" | "shell" | "console");
                    open = Some((i + 2, shell, String::new()));
                }
                Some((start, shell, body)) => {
                    if shell {
                        blocks.push((start, body));
                    }
                }
            }
        } else if let Some((_, _, body)) = open.as_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    assert!(open.is_none(), "a fenced block is not closed");
    blocks
}

/// The words of one shell line, `None` for a comment; `#` starts a comment at the start of a
/// word outside quotes. Separators (`&&`, `||`, `;`, `|`) are words of their own.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\'' => {
                in_word = true;
                for q in chars.by_ref() {
                    if q == '\'' {
                        break;
                    }
                    word.push(q);
                }
            }
            '"' => {
                in_word = true;
                while let Some(q) = chars.next() {
                    match q {
                        '"' => break,
                        '\\' => word.extend(chars.next()),
                        _ => word.push(q),
                    }
                }
            }
            '#' if !in_word => break,
            ';' | '|' | '&' => {
                if in_word {
                    out.push(std::mem::take(&mut word));
                    in_word = false;
                }
                let mut sep = c.to_string();
                if chars.peek() == Some(&c) {
                    sep.push(chars.next().unwrap());
                }
                out.push(sep);
            }
            c if c.is_whitespace() => {
                if in_word {
                    out.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            c => {
                in_word = true;
                word.push(c);
            }
        }
    }
    if in_word {
        out.push(word);
    }
    out
}

/// The commands of a page's shell blocks.
fn commands_of(page: &str, text: &str) -> Vec<Cmd> {
    let mut cmds = Vec::new();
    for (start, body) in shell_blocks(text) {
        // Join continued lines, keeping the line of each command's start.
        let mut logical: Vec<(usize, String)> = Vec::new();
        let mut continued = false;
        for (i, line) in body.lines().enumerate() {
            let (text, cont) = match line.trim_end().strip_suffix('\\') {
                Some(t) => (t.to_string(), true),
                None => (line.to_string(), false),
            };
            if continued {
                logical.last_mut().unwrap().1.push_str(&format!(" {text}"));
            } else {
                logical.push((start + i, text));
            }
            continued = cont;
        }
        for (line, text) in logical {
            let mut current = Vec::new();
            for w in words(&text).into_iter().chain([";".to_string()]) {
                if matches!(w.as_str(), "&&" | "||" | ";" | "|" | "&") {
                    if !current.is_empty() {
                        cmds.push(Cmd {
                            page: page.to_string(),
                            line,
                            words: strip_front(std::mem::take(&mut current)),
                        });
                    }
                } else {
                    current.push(w);
                }
            }
        }
    }
    cmds
}

/// `words` without leading environment assignments and wrappers (`sudo`, `time`,
/// `/usr/bin/time` with its `-f FORMAT`, `nice`).
fn strip_front(mut words: Vec<String>) -> Vec<String> {
    loop {
        let Some(first) = words.first() else {
            return words;
        };
        let assignment = first.split_once('=').is_some_and(|(k, _)| {
            !k.is_empty() && k.chars().all(|c| c == '_' || c.is_ascii_alphanumeric())
        });
        if assignment || matches!(first.as_str(), "sudo" | "time" | "nice") {
            words.remove(0);
        } else if first == "/usr/bin/time" {
            words.remove(0);
            if words.first().is_some_and(|w| w == "-f") {
                words.drain(..2.min(words.len()));
            }
        } else {
            return words;
        }
    }
}

/// Every command of every command page.
fn all_commands() -> Vec<Cmd> {
    let mut cmds = Vec::new();
    for page in command_pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        cmds.extend(commands_of(&shown(&page), &text));
    }
    cmds
}

// ---------------------------------------------------------------------------------------
// Checking commands without running them

/// The CLI as the docs name it: the one form every command uses.
const CLI: &str = "target/release/icrflow";

/// Flags whose value is a file the command writes.
const OUTPUT_FLAGS: &[&str] = &["--out", "--rrd", "--summary-json"];

/// What the checks know of the repository: its packages (name -> directory) and the help of
/// each verb of the CLI.
struct Repo {
    packages: BTreeMap<String, PathBuf>,
    help: BTreeMap<String, String>,
}

impl Repo {
    fn new() -> Repo {
        Repo {
            packages: packages(),
            help: BTreeMap::new(),
        }
    }

    /// `icrflow VERB --help`, which must succeed (the verb exists).
    fn help(&mut self, verb: &str) -> Result<&str, String> {
        if !self.help.contains_key(verb) {
            let o = icrflow(&[verb, "--help"]);
            if !o.status.success() {
                return Err(format!(
                    "`icrflow {verb}` is not a verb of the CLI: {}",
                    String::from_utf8_lossy(&o.stderr)
                ));
            }
            self.help.insert(
                verb.to_string(),
                String::from_utf8_lossy(&o.stdout).to_string(),
            );
        }
        Ok(&self.help[verb])
    }
}

/// The workspace's packages: each member's `name` and directory, from the root manifest's
/// `members`.
fn packages() -> BTreeMap<String, PathBuf> {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let members = manifest
        .split_once("members = [")
        .and_then(|(_, rest)| rest.split_once(']'))
        .map(|(list, _)| list)
        .expect("the workspace's members");
    let mut packages = BTreeMap::new();
    for member in members.split(',').map(|m| m.trim().trim_matches('"')) {
        if member.is_empty() {
            continue;
        }
        let dir = root().join(member);
        let text = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        let package = text.split_once("[package]").expect("a [package] section").1;
        let name = package
            .lines()
            .find_map(|l| l.trim().strip_prefix("name = "))
            .expect("a package name")
            .trim_matches('"')
            .to_string();
        packages.insert(name, dir);
    }
    packages
}

/// Whether `word` is meant as a path in the repository (or under `out/` or `target/`): its
/// first part is a top-level entry of the repository, or it has a file's extension.
fn is_path(word: &str) -> bool {
    if word.starts_with('-') || word.contains('$') || word.contains("://") {
        return false;
    }
    let first = word.split('/').next().unwrap();
    let ext = Path::new(word).extension().and_then(|e| e.to_str());
    (word.contains('/') && (root().join(first).exists() || first == "out" || first == "target"))
        || matches!(
            ext,
            Some(
                "toml"
                    | "stl"
                    | "obj"
                    | "urdf"
                    | "rs"
                    | "py"
                    | "sh"
                    | "md"
                    | "rrd"
                    | "png"
                    | "json"
            )
        )
}

/// The files a command writes under `out/`: its output flags' values, and the defaults of
/// `run` (`out/<stem>.rrd`) and `plan` (`out/<stem>/`).
fn outputs(cmd: &Cmd) -> Vec<String> {
    let w = &cmd.words;
    let mut out = Vec::new();
    for pair in w.windows(2) {
        if OUTPUT_FLAGS.contains(&pair[0].as_str()) {
            out.push(pair[1].clone());
        }
    }
    if w.first().is_some_and(|p| p == CLI) {
        let stem = config_of(cmd).and_then(|c| {
            Path::new(&c)
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
        });
        if let Some(stem) = stem {
            match w.get(1).map(String::as_str) {
                Some("run") if !w.iter().any(|x| x == "--rrd") => {
                    out.push(format!("out/{stem}.rrd"))
                }
                Some("plan") if !w.iter().any(|x| x == "--out") => out.push(format!("out/{stem}/")),
                _ => {}
            }
        }
    }
    out
}

/// The config a CLI command names (its first `.toml` argument).
fn config_of(cmd: &Cmd) -> Option<String> {
    cmd.words
        .iter()
        .skip(2)
        .find(|w| w.ends_with(".toml"))
        .cloned()
}

/// Checks the paths a command names: each exists in the repository, or is a file an earlier
/// command of the same page writes (`written`), or one this command writes (the value of an
/// output flag); build outputs (`target/`) are left to the build.
fn check_paths(cmd: &Cmd, written: &BTreeSet<String>) -> Vec<String> {
    let mut problems = Vec::new();
    let w = &cmd.words;
    for (i, word) in w.iter().enumerate() {
        let writes = i > 0 && OUTPUT_FLAGS.contains(&w[i - 1].as_str());
        if i == 0 && word == CLI || writes || !is_path(word) || word.starts_with("target/") {
            continue;
        }
        if word.starts_with("out/") {
            let made = written
                .iter()
                .any(|o| o == word || (o.ends_with('/') && word.starts_with(o.as_str())));
            if !made {
                problems.push(format!(
                    "{}: {word} is written by no earlier command of the page",
                    cmd.at()
                ));
            }
        } else if !root().join(word).exists() {
            problems.push(format!("{}: {word} does not exist", cmd.at()));
        }
    }
    problems
}

/// Checks a command of the CLI: the one form, a verb the CLI has, and every flag in that
/// verb's help.
fn check_cli(cmd: &Cmd, repo: &mut Repo) -> Vec<String> {
    let Some(verb) = cmd.words.get(1) else {
        return vec![format!("{}: no verb", cmd.at())];
    };
    let help = match repo.help(verb) {
        Ok(help) => help,
        Err(e) => return vec![format!("{}: {e}", cmd.at())],
    };
    let mut problems = Vec::new();
    for word in cmd.words.iter().skip(2).filter(|w| w.starts_with('-')) {
        let flag = word.split('=').next().unwrap();
        let offered = help
            .split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']' || c == '=')
            .any(|h| h == flag || h.strip_suffix("...") == Some(flag));
        if !offered {
            problems.push(format!("{}: `icrflow {verb}` has no flag {flag}", cmd.at()));
        }
    }
    problems
}

/// Checks a cargo command: its subcommand and flags are among those the docs use, each
/// package is a workspace member, and each bench, example or test exists in its package;
/// `KEY=VALUE` arguments of an example are keys its source matches on.
fn check_cargo(cmd: &Cmd, repo: &Repo) -> Vec<String> {
    let mut problems = Vec::new();
    let w = &cmd.words;
    let sub = w.get(1).map(String::as_str).unwrap_or("");
    if !matches!(sub, "build" | "test" | "bench" | "run" | "clippy" | "fmt") {
        problems.push(format!("{}: no check for `cargo {sub}`", cmd.at()));
    }
    let (ours, theirs) = match w.iter().position(|x| x == "--") {
        Some(i) => (&w[..i], &w[i + 1..]),
        None => (&w[..], &w[w.len()..]),
    };
    let mut package: Option<PathBuf> = None;
    let mut example: Option<PathBuf> = None;
    let mut i = 2;
    while i < ours.len() {
        let flag = ours[i].as_str();
        let value = ours.get(i + 1).map(String::as_str);
        match flag {
            "--release" | "--workspace" | "--bins" | "--no-run" | "--all-targets" | "--all" => {}
            "-p" | "--package" => {
                match value.and_then(|p| repo.packages.get(p)) {
                    Some(dir) => package = Some(dir.clone()),
                    None => problems.push(format!(
                        "{}: {} is not a package of the workspace",
                        cmd.at(),
                        value.unwrap_or("")
                    )),
                }
                i += 1;
            }
            "--bench" | "--example" | "--test" => {
                let dir = package.clone().unwrap_or_else(root);
                let folder = match flag {
                    "--bench" => "benches",
                    "--example" => "examples",
                    _ => "tests",
                };
                let file = dir.join(folder).join(format!("{}.rs", value.unwrap_or("")));
                if !file.is_file() {
                    problems.push(format!("{}: {} does not exist", cmd.at(), file.display()));
                } else if flag == "--example" {
                    example = Some(file);
                }
                i += 1;
            }
            other => problems.push(format!("{}: no check for cargo's {other}", cmd.at())),
        }
        i += 1;
    }
    if let Some(example) = example {
        let source = std::fs::read_to_string(example).unwrap();
        // The lockstep example's settings are config keys (`SECTION.KEY=VALUE`), its flags
        // the fields of its clap command line.
        let raw = std::fs::read_to_string(root().join("scenario/src/raw.rs")).unwrap();
        for arg in theirs {
            if let Some((name, _)) = arg.split_once('=') {
                let known = name.split_once('.').is_some_and(|(section, key)| {
                    raw.contains(&format!("pub {section}: Option<Raw"))
                        && raw.contains(&format!("pub {key}: "))
                });
                if !known {
                    problems.push(format!(
                        "{}: {name} is no SECTION.KEY of the config (scenario/src/raw.rs)",
                        cmd.at()
                    ));
                }
            } else if let Some(flag) = arg.strip_prefix("--")
                && !source.contains(&format!("    {}: ", flag.replace('-', "_")))
            {
                problems.push(format!("{}: the example takes no flag --{flag}", cmd.at()));
            }
        }
    }
    problems
}

/// Checks every command of `cmds` without running any, returning what is wrong.
fn check_statically(cmds: &[Cmd], repo: &mut Repo) -> Vec<String> {
    let mut problems = Vec::new();
    let mut written: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for cmd in cmds {
        let outs = written.entry(cmd.page.clone()).or_default();
        problems.extend(check_paths(cmd, outs));
        outs.extend(outputs(cmd));
        let program = cmd.words[0].as_str();
        match program {
            CLI => problems.extend(check_cli(cmd, repo)),
            "icrflow" => problems.push(format!(
                "{}: commands run the CLI as {CLI} (the form the README explains)",
                cmd.at()
            )),
            "cargo" => problems.extend(check_cargo(cmd, repo)),
            "pip" => {
                if cmd.words.get(1).map(String::as_str) != Some("install") {
                    problems.push(format!("{}: no check for this pip command", cmd.at()));
                }
            }
            "python" | "python3" | "rerun" => {}
            p if p.contains('/') => {
                // A script of the repository, run as a program: it must be executable.
                let file = root().join(p);
                let executable = std::fs::metadata(&file)
                    .map(|m| std::os::unix::fs::PermissionsExt::mode(&m.permissions()) & 0o111 != 0)
                    .unwrap_or(false);
                if !executable {
                    problems.push(format!("{}: {p} is not an executable file", cmd.at()));
                }
            }
            p => problems.push(format!(
                "{}: no check for the program {p}: add one to tests/docs.rs",
                cmd.at()
            )),
        }
    }
    problems
}

#[test]
fn every_command_names_what_exists_and_flags_its_program_accepts() {
    let cmds = all_commands();
    assert!(cmds.len() > 20, "only {} commands found", cmds.len());
    let problems = check_statically(&cmds, &mut Repo::new());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The checks can fail: a page naming a flag, a config, a bench, an example key or a form of
/// the CLI that do not exist is refused, each by name.
#[test]
fn the_checks_refuse_a_flag_or_file_that_does_not_exist() {
    let page = "```sh
target/release/icrflow plan config/paper_sphere.toml --no-such-flag   # a comment with --another
target/release/icrflow analyze config/no_such_config.toml
target/release/icrflow render out/never_written.rrd --at END --out out/x.png
target/release/icrflow no-such-verb config/paper_sphere.toml
icrflow validate config/paper_sphere.toml
cargo bench -p icrflow-grasp --bench no_such_bench
cargo run --release -p icrflow-nodes --example lockstep -- config/paper_sphere_mujoco.toml --no-such-seconds 60 plant.no_such_key=1
make everything
```
";
    let cmds = commands_of("fake.md", page);
    assert_eq!(cmds.len(), 8, "{cmds:?}");
    let problems = check_statically(&cmds, &mut Repo::new()).join("\n");
    for expected in [
        "has no flag --no-such-flag",
        "config/no_such_config.toml does not exist",
        "out/never_written.rrd is written by no earlier command",
        "`icrflow no-such-verb` is not a verb",
        "commands run the CLI as target/release/icrflow",
        "no_such_bench.rs does not exist",
        "plant.no_such_key is no SECTION.KEY of the config",
        "the example takes no flag --no-such-seconds",
        "no check for the program make",
    ] {
        assert!(
            problems.contains(expected),
            "{expected} not in:\n{problems}"
        );
    }
    assert!(!problems.contains("--another"), "{problems}");
}

#[test]
fn shell_words_are_read_as_a_shell_would() {
    assert_eq!(
        words(r#"A=1 "$X/bin" 'a b' c#d # e"#),
        ["A=1", "$X/bin", "a b", "c#d"]
    );
    assert_eq!(words("a && b | c; d"), ["a", "&&", "b", "|", "c", ";", "d"]);
    let cmds = commands_of(
        "p.md",
        "```sh\nX=1 sudo a \\\n  b && /usr/bin/time -f \"%e s\" c\n```\n```\nnot a command\n```\n",
    );
    let words: Vec<_> = cmds.iter().map(|c| c.words.join(" ")).collect();
    assert_eq!(words, ["a b", "c"]);
    assert_eq!(cmds[1].line, 2);
}

// ---------------------------------------------------------------------------------------
// Running the quick commands, and tying the long ones to the tests that run them

/// Configs whose plan takes a few seconds at most: their `plan` commands run as written.
const QUICK_PLANS: &[&str] = &[
    "config/paper_sphere.toml",
    "config/paper_sphere_mu003.toml",
    "config/ellipsoid_spatial.toml",
    "config/allegro_sphere.toml",
];

/// The exit status a verb gives on a config: 2 where the grasp is not force closure
/// (the docs say so), else 0.
fn expected_status(config: &str) -> i32 {
    if config.ends_with("paper_sphere_mu003.toml") {
        2
    } else {
        0
    }
}

/// `validate`, `analyze` and the quick plans run as the docs write them (a plan's files go to
/// a scratch directory, its recording is left out: that needs the visualizer's binary, which
/// the pipeline tests run), with the status the config should give.
#[test]
fn the_quick_commands_run_as_written() {
    let dir = scratch("docs-quick");
    let mut ran = 0;
    for (n, cmd) in all_commands().iter().enumerate() {
        let w = &cmd.words;
        if w[0] != CLI {
            continue;
        }
        let Some(config) = config_of(cmd) else {
            continue;
        };
        let verb = w[1].as_str();
        let quick = matches!(verb, "validate" | "analyze")
            || verb == "plan" && QUICK_PLANS.contains(&config.as_str());
        if !quick {
            continue;
        }
        let mut args: Vec<String> = Vec::new();
        let mut i = 1;
        while i < w.len() {
            match w[i].as_str() {
                "--rrd" | "--out" => i += 1,
                "--spawn-viewer" => {}
                a => args.push(a.to_string()),
            }
            i += 1;
        }
        if verb == "plan" {
            args.push("--out".into());
            args.push(dir.join(format!("plan{n}")).display().to_string());
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = icrflow(&args);
        assert_eq!(
            o.status.code(),
            Some(expected_status(&config)),
            "{}: {}",
            cmd.at(),
            String::from_utf8_lossy(&o.stderr)
        );
        ran += 1;
    }
    assert!(ran >= 10, "only {ran} quick commands ran");
}

/// The test sources that run the CLI and the nodes.
fn test_sources() -> String {
    let mut text = String::new();
    for dir in ["tests", "nodes/tests"] {
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|e| e == "rs") && !p.ends_with("tests/docs.rs") {
                text.push_str(&std::fs::read_to_string(p).unwrap());
            }
        }
    }
    text
}

/// The commands too long to run here (`run`, `render`, `monitor`, and the plans that take
/// long) are run by the tests: the config each names validates and is one a test under
/// `tests/` or `nodes/tests/` starts, and every flag is one a test passes.
#[test]
fn the_long_commands_are_run_by_the_tests() {
    let tests = test_sources();
    let mut problems = Vec::new();
    let mut checked = 0;
    for cmd in all_commands() {
        let w = &cmd.words;
        if w[0] != CLI || matches!(w[1].as_str(), "validate" | "analyze") {
            continue;
        }
        let config = config_of(&cmd);
        if w[1] == "plan" && config.as_deref().is_some_and(|c| QUICK_PLANS.contains(&c)) {
            continue;
        }
        if let Some(config) = &config {
            let o = icrflow(&["validate", config]);
            if o.status.code() != Some(expected_status(config)) {
                problems.push(format!(
                    "{}: {config} does not validate: {}",
                    cmd.at(),
                    String::from_utf8_lossy(&o.stderr)
                ));
            }
            if !config_names(config).iter().any(|n| tests.contains(n)) {
                problems.push(format!("{}: no test runs {config}", cmd.at()));
            }
        }
        if !tests.contains(&format!("\"{}\"", w[1])) {
            problems.push(format!("{}: no test runs `icrflow {}`", cmd.at(), w[1]));
        }
        for flag in w.iter().filter(|x| x.starts_with("--")) {
            if !tests.contains(&format!("\"{flag}\"")) {
                problems.push(format!("{}: no test passes {flag}", cmd.at()));
            }
        }
        checked += 1;
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    assert!(checked >= 10, "only {checked} long commands checked");
}

/// How the tests name a config: its path, its file name (joined to `config/`) or its stem
/// (`NAME.toml` appended), each quoted.
fn config_names(config: &str) -> [String; 3] {
    let path = Path::new(config);
    let name = path.file_name().unwrap().to_string_lossy();
    let stem = path.file_stem().unwrap().to_string_lossy();
    [
        format!("\"{config}\""),
        format!("\"{name}\""),
        format!("\"{stem}\""),
    ]
}

/// The README keeps the two commands CI and the tests rely on, exactly.
#[test]
fn the_readme_has_the_two_commands() {
    let cmds: Vec<String> = commands_of(
        "README.md",
        &std::fs::read_to_string(root().join("README.md")).unwrap(),
    )
    .into_iter()
    .map(|c| c.words.join(" "))
    .collect();
    for expected in [
        "scripts/setup.sh",
        "cargo build --release --workspace",
        "target/release/icrflow run config/paper_sphere.toml",
        "scripts/test.sh",
    ] {
        assert!(
            cmds.iter().take(4).any(|c| c == expected),
            "{expected} not among the README's first commands: {cmds:?}"
        );
    }
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    assert!(ci.lines().any(|l| l.trim() == "scripts/test.sh"), "{ci}");
}

// ---------------------------------------------------------------------------------------
// Links

/// The anchor GitHub gives a heading: lower case, punctuation but `-` and `_` dropped,
/// spaces as `-`.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown page's headings (a repeated one numbered as GitHub does).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if (1..=6).contains(&hashes) && line[hashes..].starts_with(' ') {
            let base = slug(&line[hashes..]);
            let n = seen.entry(base.clone()).or_insert(0);
            out.insert(if *n == 0 {
                base.clone()
            } else {
                format!("{base}-{n}")
            });
            *n += 1;
        }
    }
    out
}

/// The targets of a page's inline links and images, with their lines, outside fenced blocks
/// and code spans.
fn links(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Code spans removed: the odd-numbered parts between backticks.
        let prose: String = line
            .split('`')
            .enumerate()
            .filter(|(k, _)| k % 2 == 0)
            .map(|(_, s)| s)
            .collect::<Vec<_>>()
            .join(" ");
        let mut rest = prose.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find(')').unwrap_or(after.len());
            out.push((i + 1, after[..end].trim().to_string()));
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_relative_link_points_at_a_file_and_heading_that_exist() {
    let mut problems = Vec::new();
    let mut checked = 0;
    for page in link_pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for (line, target) in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = target.split_once('#').unwrap_or((&target, ""));
            let file = if path.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(path)
            };
            let at = format!("{}:{line}: {target}", shown(&page));
            checked += 1;
            if !file.exists() {
                problems.push(format!("{at}: no such file"));
                continue;
            }
            if !anchor.is_empty() && file.extension().is_some_and(|e| e == "md") {
                let headings = anchors(&std::fs::read_to_string(&file).unwrap());
                if !headings.contains(anchor) {
                    problems.push(format!("{at}: no heading #{anchor} there"));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    assert!(checked > 50, "only {checked} links checked");
}

#[test]
fn anchors_are_githubs() {
    let a = anchors(
        "# A\n## The paper's sphere\n## Using `plan`\n```\n# not a heading\n```\n## A\n\
         ## Python package, issue #23 (`bench/python.sh`)\n",
    );
    let expected: BTreeSet<String> = [
        "a",
        "the-papers-sphere",
        "using-plan",
        "a-1",
        "python-package-issue-23-benchpythonsh",
    ]
    .map(String::from)
    .into();
    assert_eq!(a, expected);
    assert_eq!(
        links("see [x](a.md#b) and `[y](not/a/link)`\n![p](docs/p.png)\n"),
        [(1, "a.md#b".to_string()), (2, "docs/p.png".to_string())]
    );
}
