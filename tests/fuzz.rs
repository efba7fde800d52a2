//! Fuzzing on stable Rust: mutations of every shipped case file and of the
//! fixture `.msh` meshes (byte flips, truncation, deletions, key/value swaps,
//! huge and non-finite numbers, inserted tables and keys) through the entry
//! points `xfem-cut run` uses — parse and validate, the memory guard, and for
//! small scenes meshing and the model set-up (no solve).
//!
//! Every input must be accepted or refused with a one-line error naming the
//! file; a panic counts as a failure (caught, and the input written to
//! `target/fuzz-failures/`). `XFEM_FUZZ_COUNT` sets the number of mutated
//! inputs (default 100 000; `make fuzz` runs 10⁶). The inputs in
//! `tests/fixtures/fuzz/` (ones that found a bug) run first, every time.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use xfem_cut::scene::Scene;

/// SplitMix64: a small deterministic generator (the run is reproducible).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers and tokens that have broken parsers and allocators elsewhere.
const NUMBERS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "+inf",
    "-nan",
    "0",
    "-0.0",
    "-1",
    "1e308",
    "-1e308",
    "1e400",
    "5e-324",
    "1e-320",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "100000000000000",
    "1000",
    "1001",
    "4294967296",
    "0.5",
    "0.4999999999",
    "1e15",
    "3",
    "2",
];

const TOKENS: &[&str] = &[
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    "=",
    "\"",
    "'",
    ",",
    ".",
    "\n",
    "#",
    "\\",
    "\u{0}",
    "é",
    "[[cut]]\n",
    "[[fix]]\n",
    "[[probe]]\n",
    "[analysis]\n",
    "[body]\n",
    "[gravity]\n",
    "snap = 0.3\n",
    "front = \"tip\"\n",
    "front = \"extend\"\n",
    "tip_radius = 0.001\n",
    "surface = \"incision.stl\"\n",
    "blade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]\n",
    "travel = [0.015, 0.0, 0.0]\n",
    "start = 0.1\n",
    "end = 0.05\n",
    "path = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\n",
    "times = [0.2, 0.1]\n",
    "steps = 100000000000000\n",
    "levels = [[1000, 1000, 1000]]\n",
    "levels = [[1, 1, 1]]\n",
    "mesh = \"missing.msh\"\n",
    "element = \"tet10\"\n",
    "type = \"dynamic\"\n",
    "type = \"static\"\n",
    "formulation = \"corotational\"\n",
    "output_every = 1\n",
    "mass = \"consistent\"\n",
    "linear_solver = \"pcg\"\n",
    "components = \"\"\n",
    "displacement = [0.0, 0.0, 1e300]\n",
    "dt = 1e-300\n",
    "x = 1\n",
    "= 1\n",
    "a.b.c = 1\n",
    "points = []\n",
    "levels = []\n",
];

/// One random edit of `text`.
fn mutate_once(rng: &mut Rng, text: &mut Vec<u8>) {
    let n = text.len();
    match rng.below(10) {
        // Byte flip: a printable character, a token byte, or any byte.
        0 => {
            if n > 0 {
                let i = rng.below(n);
                text[i] = match rng.below(3) {
                    0 => b' ' + rng.below(95) as u8,
                    1 => *rng.pick(b"[]{}=\",.#\n0123456789-+eE"),
                    _ => rng.next() as u8,
                };
            }
        }
        // Truncation.
        1 => text.truncate(rng.below(n + 1)),
        // Delete a short range.
        2 => {
            if n > 0 {
                let i = rng.below(n);
                let j = (i + 1 + rng.below(24)).min(n);
                text.drain(i..j);
            }
        }
        // Insert a token at a line start or anywhere.
        3 | 4 => {
            let tok = rng.pick(TOKENS).as_bytes();
            let at = if rng.below(2) == 0 {
                line_starts(text).get(rng.below(n)).copied().unwrap_or(0)
            } else {
                rng.below(n + 1)
            };
            let at = at.min(text.len());
            text.splice(at..at, tok.iter().copied());
        }
        // Replace a number with a hostile one.
        5 | 6 => {
            let spans = number_spans(text);
            if !spans.is_empty() {
                let (i, j) = *rng.pick(&spans);
                text.splice(i..j, rng.pick(NUMBERS).bytes());
            }
        }
        // Swap the values (or the keys) of two `key = value` lines.
        7 => swap_key_values(rng, text),
        // Swap, duplicate or delete whole lines.
        _ => {
            let mut lines: Vec<Vec<u8>> = text.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
            let m = lines.len();
            let (a, b) = (rng.below(m), rng.below(m));
            match rng.below(3) {
                0 => lines.swap(a, b),
                1 => {
                    let l = lines[a].clone();
                    lines.insert(b, l);
                }
                _ => {
                    lines.remove(a);
                }
            }
            *text = lines.join(&b'\n');
        }
    }
}

fn line_starts(text: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain(
            text.iter()
                .enumerate()
                .filter(|(_, &b)| b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect()
}

/// Byte ranges of numeric literals.
fn number_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let c = text[i];
        let starts =
            c.is_ascii_digit() || (c == b'-' && text.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && (i == 0 || !text[i - 1].is_ascii_alphanumeric() && text[i - 1] != b'_') {
            let mut j = i + 1;
            while j < text.len() && (text[j].is_ascii_alphanumeric() || b".+-_".contains(&text[j]))
            {
                j += 1;
            }
            spans.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    spans
}

fn swap_key_values(rng: &mut Rng, text: &mut Vec<u8>) {
    let s = String::from_utf8_lossy(text).into_owned();
    let mut lines: Vec<String> = s.split('\n').map(str::to_string).collect();
    let kv: Vec<usize> = (0..lines.len())
        .filter(|&i| lines[i].contains(" = "))
        .collect();
    if kv.len() < 2 {
        return;
    }
    let (a, b) = (*rng.pick(&kv), *rng.pick(&kv));
    let (ka, va) = lines[a]
        .split_once(" = ")
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .unwrap();
    let (kb, vb) = lines[b]
        .split_once(" = ")
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .unwrap();
    if rng.below(2) == 0 {
        lines[a] = format!("{ka} = {vb}");
        lines[b] = format!("{kb} = {va}");
    } else {
        lines[a] = format!("{kb} = {va}");
        lines[b] = format!("{ka} = {vb}");
    }
    *text = lines.join("\n").into_bytes();
}

fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let mut t = seed.to_vec();
    for _ in 0..1 + rng.below(3) {
        mutate_once(rng, &mut t);
    }
    t
}

/// A refusal must be one line naming the file.
fn check_message(msg: &str, file: &str) -> Result<(), String> {
    if msg.contains('\n') || msg.trim().is_empty() || !msg.contains(file) {
        return Err(format!("not a one-line error naming {file}: {msg:?}"));
    }
    Ok(())
}

/// Scenes this small are meshed and set up (no solve); larger ones only pass the memory guard.
const SETUP_BYTES: f64 = 4.0e6;

/// What `xfem-cut run` does before solving: parse and validate, the memory
/// guard, and (for small scenes, every `setup_every`-th) the mesh and model set-up.
fn case_entry(text: &[u8], path: &Path, set_up: bool) -> Result<(), String> {
    let file = path.display().to_string();
    let text = String::from_utf8_lossy(text);
    let scene = match Scene::parse(&text, path) {
        Ok(s) => s,
        Err(e) => return check_message(&e.to_string(), &file),
    };
    for level in 0..scene.n_levels() {
        if let Err(e) = scene.check_memory(level) {
            check_message(&e.to_string(), &file)?;
        }
    }
    if !set_up || scene.estimate(0).is_none_or(|e| e.total() > SETUP_BYTES) {
        return Ok(());
    }
    match scene.mesh(0).and_then(|m| scene.build(m)) {
        Ok(_) => Ok(()),
        Err(e) => check_message(&e.to_string(), &file),
    }
}

/// A mesh as `xfem-cut run --mesh` reads it, then set up under a scene that fixes everything.
fn msh_entry(bytes: &[u8], path: &Path, scene: &Scene) -> Result<(), String> {
    let file = path.display().to_string();
    let mesh = match xfem_cut::io::parse_msh(bytes, path) {
        Ok(m) => m.mesh,
        Err(e) => return check_message(&e.to_string(), &file),
    };
    if mesh.n_elements() > 20_000 {
        return Ok(());
    }
    match scene.build(mesh) {
        Ok(_) => Ok(()),
        // Scene errors name the scene's file.
        Err(e) => check_message(&e.to_string(), &scene.file.display().to_string()),
    }
}

const MSH_SCENE: &str = r#"
name = "fuzz_msh"
[body]
mesh = "fixture.msh"
[material]
young = 1.0e5
poisson = 0.3
density = 1000.0
[[fix]]
min = [-inf, -inf, -inf]
max = [inf, inf, inf]
components = "z"
[analysis]
type = "dynamic"
dt = 0.01
steps = 2
"#;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `entry` on `input` catching panics; a failure is written out for the corpus.
fn run_one(
    entry: &dyn Fn(&[u8]) -> Result<(), String>,
    input: &[u8],
    name: &str,
    failures: &mut Vec<String>,
) {
    let outcome = catch_unwind(AssertUnwindSafe(|| entry(input)));
    let why = match outcome {
        Ok(Ok(())) => return,
        Ok(Err(why)) => why,
        Err(p) => format!(
            "panic: {}",
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        ),
    };
    let dir = root().join("target/fuzz-failures");
    let _ = std::fs::create_dir_all(&dir);
    let out = dir.join(format!("{}-{}", failures.len(), name));
    let _ = std::fs::write(&out, input);
    failures.push(format!("{}: {why}", out.display()));
}

#[test]
fn mutated_cases_and_meshes_are_accepted_or_refused_in_one_line() {
    let count: usize = std::env::var("XFEM_FUZZ_COUNT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    // Every shipped case, in cases/ and its folders (cut surfaces beside them).
    let mut cases: Vec<PathBuf> = Vec::new();
    let mut dirs = vec![root().join("cases")];
    while let Some(dir) = dirs.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|e| e == "toml") {
                cases.push(p);
            }
        }
    }
    cases.sort();
    let meshes: Vec<PathBuf> = [
        "gmsh_cube_tet4_binary.msh",
        "gmsh_cube_tet10_ascii.msh",
        "gmsh_cube_tet10_binary.msh",
    ]
    .iter()
    .map(|n| root().join("tests/fixtures").join(n))
    .collect();
    let case_seeds: Vec<(PathBuf, Vec<u8>)> = cases
        .iter()
        .map(|p| (p.clone(), std::fs::read(p).unwrap()))
        .collect();
    let msh_seeds: Vec<Vec<u8>> = meshes.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let msh_scene = Scene::parse(MSH_SCENE, &root().join("tests/fixtures/fuzz_msh.toml")).unwrap();
    let msh_path = root().join("tests/fixtures/fuzzed.msh");
    assert!(!case_seeds.is_empty());

    // Quiet panics: they are counted, not printed one by one.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut failures = Vec::new();

    // The corpus first: inputs that found bugs.
    let corpus = root().join("tests/fixtures/fuzz");
    let mut corpus_files: Vec<PathBuf> = std::fs::read_dir(&corpus)
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    corpus_files.sort();
    for p in &corpus_files {
        let bytes = std::fs::read(p).unwrap();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.ends_with(".msh") {
            run_one(
                &|b| msh_entry(b, &msh_path, &msh_scene),
                &bytes,
                &name,
                &mut failures,
            );
        } else {
            let path = root().join("cases").join(&name);
            run_one(
                &|b| case_entry(b, &path, true),
                &bytes,
                &name,
                &mut failures,
            );
        }
    }

    let mut rng = Rng(0x5EED_CA5E);
    let (mut accepted, mut refused) = (0usize, 0usize);
    let start = std::time::Instant::now();
    for i in 0..count {
        // Four case mutations for every mesh mutation.
        if i % 5 == 4 {
            let seed = rng.pick(&msh_seeds).clone();
            let input = mutate(&mut rng, &seed);
            run_one(
                &|b| msh_entry(b, &msh_path, &msh_scene),
                &input,
                "fuzzed.msh",
                &mut failures,
            );
        } else {
            let (path, seed) = rng.pick(&case_seeds);
            let input = mutate(&mut rng, seed);
            let set_up = i % 20 == 0;
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let text = String::from_utf8_lossy(&input);
            match Scene::parse(&text, path) {
                Ok(_) => accepted += 1,
                Err(_) => refused += 1,
            }
            run_one(
                &|b| case_entry(b, path, set_up),
                &input,
                &name,
                &mut failures,
            );
        }
        if failures.len() >= 20 {
            break;
        }
    }
    std::panic::set_hook(hook);
    println!(
        "fuzz: {count} inputs ({} case files, {} meshes, corpus {}), cases accepted {accepted}, refused {refused}, in {:.1} s",
        case_seeds.len(),
        msh_seeds.len(),
        corpus_files.len(),
        start.elapsed().as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
