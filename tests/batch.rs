//! `goniospec batch`: plans, shards, resumption and byte-identical merges.

mod common;

use std::path::{Path, PathBuf};

use common::*;

fn ok(args: &[&str]) -> String {
    let (code, out, err) = goniospec(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    out
}

/// `batch plan PLAN -o DIR`.
fn plan_into(plan: &Path, dir: &Path) -> String {
    ok(&[
        "batch",
        "plan",
        plan.to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
    ])
}

/// The whole plan in one process: plan, run every unit, merge.
fn one_process(plan: &Path, dir: &Path) {
    plan_into(plan, dir);
    ok(&["batch", "run", dir.to_str().unwrap()]);
    ok(&["batch", "merge", dir.to_str().unwrap()]);
}

/// A plan of two materials (4 + 2 directions, two representations) beside `dir`; the
/// second sets knobs of `simulate` (a plan can set every one).
fn plan(dir: &Path, rays: u64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let root = root().display().to_string();
    let p = dir.join("plan.toml");
    std::fs::write(
        &p,
        format!(
            "[defaults]\ntheta_i = [0, 20, 40, 60]\nwavelengths = \"400:700:50\"\nrays = {rays}\nrepresentations = [\"table\", \"kdtree\"]\n\n[[material]]\nsample = \"{root}/meshes/rough-gold.toml\"\nname = \"gold\"\n\n[[material]]\nsample = \"{root}/meshes/thin-film-600nm.toml\"\ntheta_i = [10, 30]\nseed = 7\ncoherence_radius_nm = 2000.0\ntheta_o_bins = 30\n"
        ),
    )
    .unwrap();
    p
}

fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    [
        "gold.gsa",
        "gold-table.gsb",
        "gold-kdtree.gsb",
        "thin-film-600nm.gsa",
        "thin-film-600nm-table.gsb",
    ]
    .iter()
    .map(|f| {
        (
            f.to_string(),
            std::fs::read(dir.join("out").join(f)).unwrap(),
        )
    })
    .collect()
}

/// Split 1, 2 and 5 ways, shards run in scrambled orders, the merged files are the same
/// bytes; and they are the bytes of simulating each material in one run.
#[test]
fn shards_merge_to_the_bytes_of_one_run() {
    let d = scratch("batch-shards");
    let p = plan(&d, 128);
    let mut results = Vec::new();
    for (n, order) in [
        (1usize, vec![1usize]),
        (2, vec![2, 1]),
        (5, vec![3, 5, 1, 4, 2]),
    ] {
        let b = d.join(format!("b{n}"));
        let out = plan_into(&p, &b);
        assert!(out.contains("planned 6 units (2 materials"), "{out}");
        for i in order {
            ok(&[
                "batch",
                "run",
                b.to_str().unwrap(),
                "--shard",
                &format!("{i}/{n}"),
            ]);
        }
        ok(&["batch", "merge", b.to_str().unwrap()]);
        results.push(outputs(&b));
    }
    assert_eq!(results[0], results[1]);
    assert_eq!(results[0], results[2]);
    let direct = d.join("direct.gsa");
    ok(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "0,20,40,60",
        "--wavelengths",
        "400:700:50",
        "--rays",
        "128",
        "-o",
        direct.to_str().unwrap(),
    ]);
    assert_eq!(
        std::fs::read(&direct).unwrap(),
        results[0][0].1,
        "merged gold against simulate"
    );
    let direct = d.join("film.gsa");
    ok(&[
        "simulate",
        "meshes/thin-film-600nm.toml",
        "--theta-i",
        "10,30",
        "--wavelengths",
        "400:700:50",
        "--rays",
        "128",
        "--seed",
        "7",
        "--coherence-radius-nm",
        "2000",
        "--theta-o-bins",
        "30",
        "-o",
        direct.to_str().unwrap(),
    ]);
    assert_eq!(
        std::fs::read(&direct).unwrap(),
        results[0][3].1,
        "merged film against simulate"
    );
}

/// A corrupted unit is named by status and merge; rerunning its shard repairs it (and
/// only it), giving the same bytes. Missing units are named too.
#[test]
fn corrupt_and_missing_units_are_named_and_repaired_by_a_rerun() {
    let d = scratch("batch-repair");
    let p = plan(&d, 64);
    let b = d.join("b");
    let bs = b.to_str().unwrap();
    ok(&["batch", "plan", p.to_str().unwrap(), "-o", bs]);
    ok(&["batch", "run", bs, "--shard", "1/2"]);
    let (code, out, _) = goniospec(&["batch", "status", bs]);
    assert_eq!(code, 1);
    assert!(
        out.contains("6 units: 3 done, 3 missing, 0 failed"),
        "{out}"
    );
    let (code, _, err) = goniospec(&["batch", "merge", bs]);
    assert_eq!(code, 1);
    assert!(
        err.contains("missing") && err.contains("units/gold/0001.gsa"),
        "{err}"
    );
    ok(&["batch", "run", bs, "--shard", "2/2"]);
    ok(&["batch", "merge", bs]);
    let good = outputs(&b);
    // Flip a byte inside a unit's payload.
    let unit = b.join("units/gold/0002.gsa");
    let mut bytes = std::fs::read(&unit).unwrap();
    let k = bytes.len() / 2;
    bytes[k] ^= 0x20;
    std::fs::write(&unit, bytes).unwrap();
    let (code, out, _) = goniospec(&["batch", "status", bs]);
    assert_eq!(code, 1);
    assert!(
        out.contains("failed: unit 2 (units/gold/0002.gsa)") && out.contains("checksum"),
        "{out}"
    );
    let (code, _, err) = goniospec(&["batch", "merge", bs]);
    assert_eq!(code, 1);
    assert!(err.contains("unit 2 (units/gold/0002.gsa)"), "{err}");
    let out = ok(&["batch", "run", bs, "--shard", "1/2"]);
    assert!(out.contains("ran 1 units, skipped 2"), "{out}");
    ok(&["batch", "merge", bs]);
    assert_eq!(outputs(&b), good);
    // A unit of another plan (another seed) in its place is refused.
    let other = d.join("other");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("rays = 64", "rays = 64\nseed = 99");
    let p2 = d.join("plan2.toml");
    std::fs::write(&p2, text).unwrap();
    plan_into(&p2, &other);
    ok(&["batch", "run", other.to_str().unwrap()]);
    std::fs::copy(
        other.join("units/gold/0000.gsa"),
        b.join("units/gold/0000.gsa"),
    )
    .unwrap();
    let (code, _, err) = goniospec(&["batch", "merge", bs]);
    assert_eq!(code, 1);
    assert!(
        err.contains("unit 0") && err.contains("another plan"),
        "{err}"
    );
}

/// A shard killed with SIGKILL mid-run leaves only whole units (writes are atomic); the
/// rerun completes the batch with the same bytes as an uninterrupted run.
#[test]
fn a_killed_shard_resumes_to_the_same_bytes() {
    let d = scratch("batch-kill");
    // 0.4 s or more per unit on two cores (rough gold's; the film's 1.7 s): the kill, 30 ms
    // after the first unit is written, lands inside a unit.
    let p = plan(&d, 50_000);
    let whole = d.join("whole");
    one_process(&p, &whole);
    let b = d.join("b");
    plan_into(&p, &b);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .args(["batch", "run", b.to_str().unwrap()])
        .current_dir(root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until the first unit is written, then kill while later ones run.
    let first = b.join("units/gold/0000.gsa");
    let t0 = std::time::Instant::now();
    while !first.exists() && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(30));
    child.kill().unwrap();
    child.wait().unwrap();
    let (_, out, _) = goniospec(&["batch", "status", b.to_str().unwrap()]);
    assert!(
        out.contains(" 0 failed"),
        "a killed unit must not look finished or corrupt: {out}"
    );
    ok(&["batch", "run", b.to_str().unwrap()]);
    ok(&["batch", "merge", b.to_str().unwrap()]);
    assert_eq!(outputs(&b), outputs(&whole));
}

/// GNU parallel runs the printed command (2 and 5 shards, 2 at a time) to the same bytes; the
/// Slurm scripts hold the array, its concurrency limit and the chained merge.
#[test]
fn gnu_parallel_and_slurm_launchers() {
    let d = scratch("batch-launch");
    let p = plan(&d, 64);
    let one = d.join("one");
    one_process(&p, &one);
    for shards in ["2", "5"] {
        let b = d.join(format!("par{shards}"));
        plan_into(&p, &b);
        let cmd = ok(&[
            "batch",
            "parallel",
            b.to_str().unwrap(),
            "--shards",
            shards,
            "--jobs",
            "2",
        ]);
        assert!(
            cmd.contains("--joblog")
                && cmd.contains("--resume-failed")
                && cmd.contains(&format!("--shard {{}}/{shards}")),
            "{cmd}"
        );
        let status = std::process::Command::new("bash")
            .args(["-c", cmd.trim()])
            .current_dir(root())
            .status()
            .expect("GNU parallel (scripts/install-deps.sh installs it)");
        assert!(status.success());
        ok(&["batch", "merge", b.to_str().unwrap()]);
        assert_eq!(
            outputs(&b),
            outputs(&one),
            "{shards} shards under GNU parallel"
        );
    }
    let b = d.join("par2");
    let out = ok(&[
        "batch",
        "slurm",
        b.to_str().unwrap(),
        "--shards",
        "6",
        "--limit",
        "3",
    ]);
    assert!(out.contains("submit.sh"), "{out}");
    let units = std::fs::read_to_string(b.join("units.sbatch")).unwrap();
    assert!(
        units.contains("#SBATCH --array=1-6%3") && units.contains("batch run"),
        "{units}"
    );
    let submit = std::fs::read_to_string(b.join("submit.sh")).unwrap();
    assert!(
        submit.contains("--dependency=afterok:") && submit.contains("merge.sbatch"),
        "{submit}"
    );
}

/// A plan with a bad sample fails at plan time, naming the material; so do bad settings.
#[test]
fn bad_plans_fail_at_plan_time() {
    let d = scratch("batch-bad");
    for (body, says) in [
        (
            "[defaults]\ntheta_i = [0]\n[[material]]\nsample = \"nowhere.toml\"\n",
            "nowhere.toml",
        ),
        (
            "[defaults]\ntheta_i = []\n[[material]]\nsample = \"SAMPLE\"\n",
            "no incident directions",
        ),
        (
            "[defaults]\ncoherence_radius_nm = -1.0\n[[material]]\nsample = \"SAMPLE\"\n",
            "coherence_radius_nm: must be positive",
        ),
        (
            "[defaults]\ncoherence = \"laser\"\n[[material]]\nsample = \"SAMPLE\"\n",
            "unknown coherence 'laser'",
        ),
        (
            "[defaults]\ntheta_i = [95]\n[[material]]\nsample = \"SAMPLE\"\n",
            "[0, 90)",
        ),
        (
            "[defaults]\ntheta_i = [0]\nrays = 0\n[[material]]\nsample = \"SAMPLE\"\n",
            "rays: must be at least 1",
        ),
        (
            "[defaults]\ntheta_i = [0]\nrepresentations = [\"cube\"]\n[[material]]\nsample = \"SAMPLE\"\n",
            "unknown representation",
        ),
        (
            "[defaults]\ntheta_i = [0]\n[[material]]\nsample = \"SAMPLE\"\n[[material]]\nsample = \"SAMPLE\"\n",
            "two materials are named",
        ),
        (
            "[defaults]\ntheta_i = [0]\nwavelengths = \"700:400:10\"\n[[material]]\nsample = \"SAMPLE\"\n",
            "material 1",
        ),
        (
            "[defaults]\ntheta_i = [0]\ncolour = 1\n[[material]]\nsample = \"SAMPLE\"\n",
            "colour",
        ),
        // Issue 47: what every unit would refuse, refused now, in simulate's words.
        (
            "[defaults]\ntheta_i = [0]\ncoherence = \"diffraction\"\n[[material]]\nsample = \"PAINT\"\n",
            "closed bodies",
        ),
        (
            "[defaults]\ntheta_i = [0]\ncoherence = \"diffraction\"\n[[material]]\nsample = \"WHITE\"\n",
            "random phases",
        ),
        (
            "[defaults]\ntheta_i = [0]\ntolerance = 0.05\n[[material]]\nsample = \"SAMPLE\"\n",
            "tolerance makes each direction's number of trees adaptive",
        ),
        (
            "[defaults]\ntheta_i = [0]\ntarget_stderr = 0.05\n[[material]]\nsample = \"SAMPLE\"\n",
            "target_stderr makes each direction's number of trees adaptive",
        ),
        (
            "[defaults]\ntheta_i = [0]\ncoherence = \"diffraction\"\nrays = 400000000\n[[material]]\nsample = \"SAMPLE\"\n",
            "GB",
        ),
        (
            "[defaults]\ntheta_i = [0]\n[[material]]\nsample = \"SAMPLE\"\nname = \"LONG\"\n",
            "at most 200",
        ),
    ] {
        let sample = format!("{}/meshes/rough-gold.toml", root().display());
        let paint = format!("{}/meshes/metallic-paint.toml", root().display());
        let white = format!("{}/meshes/paint-pigments.toml", root().display());
        let p = d.join("plan.toml");
        std::fs::write(
            &p,
            body.replace("SAMPLE", &sample)
                .replace("PAINT", &paint)
                .replace("WHITE", &white)
                .replace("LONG", &"n".repeat(250)),
        )
        .unwrap();
        let (code, _, err) = goniospec(&[
            "batch",
            "plan",
            p.to_str().unwrap(),
            "-o",
            d.join("b").to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{body}");
        assert!(err.contains(says), "{body}: {err}");
    }
    // A plan named like the manifest, in the batch folder, is not overwritten.
    let sample = format!("{}/meshes/rough-gold.toml", root().display());
    let inplace = d.join("inplace");
    std::fs::create_dir_all(&inplace).unwrap();
    let m = inplace.join("manifest.toml");
    let body = format!("[defaults]\ntheta_i = [0]\n[[material]]\nsample = \"{sample}\"\n");
    std::fs::write(&m, &body).unwrap();
    let (code, _, err) = goniospec(&[
        "batch",
        "plan",
        m.to_str().unwrap(),
        "-o",
        inplace.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("refusing to overwrite"), "{err}");
    assert_eq!(std::fs::read_to_string(&m).unwrap(), body);
    let (code, _, err) = goniospec(&["batch", "run", d.join("nothing").to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("batch plan"), "{err}");
    let (code, _, err) = goniospec(&["batch", "run", d.to_str().unwrap(), "--shard", "3/2"]);
    assert_eq!(code, 2);
    assert!(err.contains("1 <= I <= N"), "{err}");
}

/// Issue 30: a manifest edited after `plan` is refused by status, run and merge with exit 1
/// and a message, never a panic, a unit filed under another angle, an empty accumulator or
/// a unit output written over the manifest. Each edit is applied to a freshly planned copy.
#[test]
fn an_edited_manifest_is_refused_not_trusted() {
    let d = scratch("batch-edited");
    let p = plan(&d, 8);
    let good = d.join("good");
    plan_into(&p, &good);
    let text = std::fs::read_to_string(good.join("manifest.toml")).unwrap();
    // The units as plan wrote them, for the edits to find.
    assert!(text.contains("material = \"gold\""), "{text}");
    assert!(text.contains("theta_i_deg = 20.0"), "{text}");
    for (tag, from, to) in [
        // A unit naming a material the manifest does not hold (panicked).
        ("unknown", "material = \"gold\"", "material = \"silver\""),
        // A unit's angle edited: its data would be filed under 45 degrees.
        ("unit-angle", "theta_i_deg = 20.0", "theta_i_deg = 45.0"),
        // A material's list edited 0 -> 1: 0-degree data labelled 1 degree.
        ("list", "theta_i = [0.0,", "theta_i = [1.0,"),
        // An empty list (wrote a .gsa that info rejects).
        ("empty", "theta_i = [10.0, 30.0]", "theta_i = []"),
        // A unit's output sent over the manifest.
        (
            "output",
            "output = \"units/gold/0000.gsa\"",
            "output = \"manifest.toml\"",
        ),
        (
            "outside",
            "output = \"units/gold/0001.gsa\"",
            "output = \"../elsewhere.gsa\"",
        ),
    ] {
        assert!(
            text.contains(from),
            "{tag}: the manifest has no '{from}':\n{text}"
        );
        let dir = d.join(tag);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("manifest.toml"), text.replacen(from, to, 1)).unwrap();
        for cmd in ["status", "run", "merge"] {
            let (code, _, err) = goniospec(&["batch", cmd, dir.to_str().unwrap()]);
            assert_eq!(code, 1, "{tag}, batch {cmd}: exit {code}: {err}");
            assert!(err.contains("edited"), "{tag}, batch {cmd}: {err}");
        }
        assert_eq!(
            std::fs::read_to_string(dir.join("manifest.toml")).unwrap(),
            text.replacen(from, to, 1),
            "{tag}: the manifest was changed"
        );
        assert!(!dir.join("units").exists() && !d.join("elsewhere.gsa").exists());
    }
    // The unedited manifest still reads: status lists its units as missing.
    let (code, out, err) = goniospec(&["batch", "status", good.to_str().unwrap()]);
    assert!(
        code == 1 && out.contains("0 done") && !err.contains("edited"),
        "{out}{err}"
    );
}

/// Issue 30: a batch folder whose name is shell code (`inj$(touch INJECTED)x`, with a `"`
/// and a `'`) runs under GNU parallel and through the Slurm scripts (run here by bash with
/// Slurm's array variables) without running that code, and the batch completes.
#[test]
fn a_hostile_folder_name_never_reaches_a_shell_unquoted() {
    let d = scratch("batch-quote");
    let p = plan(&d, 8);
    let hostile = d.join("inj$(touch INJECTED)x \"q' `touch TICK`");
    plan_into(&p, &hostile);
    let cmd = ok(&[
        "batch",
        "parallel",
        hostile.to_str().unwrap(),
        "--shards",
        "2",
        "--jobs",
        "2",
    ]);
    let status = std::process::Command::new("bash")
        .args(["-c", cmd.trim()])
        .current_dir(&d)
        .status()
        .expect("GNU parallel (scripts/install-deps.sh installs it)");
    assert!(status.success(), "{cmd}");
    ok(&["batch", "merge", hostile.to_str().unwrap()]);
    // The Slurm array script, as a node would run it: task 1 of 1 reruns nothing (every
    // unit is done) and exits 0.
    let hint = ok(&["batch", "slurm", hostile.to_str().unwrap(), "--shards", "1"]);
    // The printed hint pastes into a shell as one word: the script's own path.
    let line = hint
        .lines()
        .find_map(|l| l.strip_prefix("submit with: bash "))
        .unwrap_or_else(|| panic!("{hint}"));
    let echoed = std::process::Command::new("bash")
        .args(["-c", &format!("printf '%s' {line}")])
        .current_dir(&d)
        .output()
        .unwrap();
    let want = std::fs::canonicalize(&hostile).unwrap().join("submit.sh");
    assert_eq!(
        String::from_utf8_lossy(&echoed.stdout),
        want.to_str().unwrap()
    );
    let status = std::process::Command::new("bash")
        .arg(hostile.join("units.sbatch"))
        .env("SLURM_ARRAY_TASK_ID", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "1")
        .current_dir(&d)
        .status()
        .unwrap();
    assert!(status.success());
    let status = std::process::Command::new("bash")
        .arg(hostile.join("merge.sbatch"))
        .current_dir(&d)
        .status()
        .unwrap();
    assert!(status.success());
    for dir in [d.as_path(), hostile.as_path(), root()] {
        for marker in ["INJECTED", "TICK"] {
            assert!(
                !dir.join(marker).exists(),
                "{marker} was created in {}: the folder name ran as code",
                dir.display()
            );
        }
    }
    assert!(hostile.join("out").join("gold.gsa").is_file());
}

/// Issue 30: a sample in a folder whose name is not UTF-8 is named in the plan's error (it
/// read "path contains invalid UTF-8 characters", naming nothing).
#[test]
fn a_non_utf8_sample_folder_is_named() {
    use std::os::unix::ffi::OsStrExt;
    let d = scratch("batch-utf8");
    let folder = d.join(std::ffi::OsStr::from_bytes(b"s\xffx"));
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::copy(
        root().join("meshes/flat-soap-film.toml"),
        folder.join("f.toml"),
    )
    .unwrap();
    std::fs::write(
        folder.join("p.toml"),
        "[defaults]\ntheta_i = [0]\nrays = 4\n[[material]]\nsample = \"f.toml\"\nname = \"f\"\n",
    )
    .unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .arg("batch")
        .arg("plan")
        .arg(folder.join("p.toml"))
        .arg("-o")
        .arg(d.join("o"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("not valid UTF-8") && err.contains("f.toml") && err.contains("rename"),
        "{err}"
    );
}

/// Issue 47, the user's walk: a three-material library with one material its simulation
/// refuses (a meshed 5-pair quarter-wave mirror, whose ray series diverges: "did not
/// converge"). `batch run` runs the others, keeps the refusal beside the unit and exits 1
/// naming it; every unit's warnings are kept beside it (the wavy film's validity warning)
/// and counted by `status`; `merge` merges the two others, carries their warnings into
/// `out/NAME.warnings` and leaves the mirror out with its reason in `out/mirror.failed`;
/// `report` writes the page for the rest, the mirror's row marked with that reason, and
/// exits 1. A rerun skips the refused unit unless asked.
#[test]
fn one_bad_material_is_marked_and_the_library_is_written() {
    let d = scratch("batch-walk");
    let (media, layers) = quarter_wave_mirror(5);
    std::fs::write(
        d.join("mirror.toml"),
        stack_toml("mirror", "mesh", media, &layers, "glass"),
    )
    .unwrap();
    let r = root().display().to_string();
    let p = d.join("plan.toml");
    std::fs::write(
        &p,
        format!(
            "[defaults]\ntheta_i = [0, 30]\nwavelengths = \"400:700:50\"\nrays = 16\n\n\
             [[material]]\nsample = \"{r}/meshes/rough-gold.toml\"\nname = \"gold\"\n\n\
             [[material]]\nsample = \"{r}/meshes/thin-film-600nm.toml\"\nname = \"film\"\n\n\
             [[material]]\nsample = \"mirror.toml\"\nname = \"mirror\"\n"
        ),
    )
    .unwrap();
    let b = d.join("b");
    let bs = b.to_str().unwrap();
    plan_into(&p, &b);
    let (code, out, err) = goniospec(&["batch", "run", bs]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        out.contains("ran 4 units") && out.contains("2 refused"),
        "{out}"
    );
    assert!(
        err.contains("refused: unit 4 (mirror at 0 deg)") && err.contains("did not converge"),
        "{err}"
    );
    assert!(err.contains("warning: unit 2 (film)"), "{err}");
    assert!(b.join("units/mirror/0000.refused").is_file());
    assert!(b.join("units/film/0000.warnings").is_file());
    // The text files are copies: the commands read each unit's warnings from its
    // checksummed accumulator, so a deleted copy hides nothing and a forged one adds nothing.
    std::fs::remove_file(b.join("units/film/0000.warnings")).unwrap();
    std::fs::write(b.join("units/gold/0001.warnings"), "FORGED\n").unwrap();
    let (code, out, _) = goniospec(&["batch", "status", bs]);
    assert_eq!(code, 1);
    assert!(
        out.contains("6 units: 4 done, 0 missing, 2 failed") && out.contains("done with warnings"),
        "{out}"
    );
    assert!(out.contains("refused by the simulation"), "{out}");
    // A rerun skips what was refused (and says so), unless asked.
    let (code, _, err) = goniospec(&["batch", "run", bs]);
    assert_eq!(code, 1);
    assert!(err.contains("refused before (--retry-refused"), "{err}");
    let (code, out, err) = goniospec(&["batch", "merge", bs]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("merged 2 of 3 materials"), "{out}");
    assert!(
        err.contains("mirror") && err.contains("out/NAME.failed"),
        "{err}"
    );
    assert!(err.contains("warning: film: theta_i 0 deg:"), "{err}");
    assert!(b.join("out/gold.gsa").is_file() && b.join("out/film.gsa").is_file());
    assert!(b.join("out/mirror.failed").is_file() && !b.join("out/mirror.gsa").exists());
    let warnings = std::fs::read_to_string(b.join("out/film.warnings")).unwrap();
    assert!(warnings.starts_with("theta_i 0 deg: "), "{warnings}");
    assert!(
        !err.contains("FORGED") && !b.join("out/gold.warnings").exists(),
        "{err}"
    );
    let (code, out, err) = goniospec(&["batch", "report", bs, "--no-fit"]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("3 materials, 1 left out"), "{out}");
    assert!(err.contains("left out: mirror: not merged"), "{err}");
    let html = std::fs::read_to_string(b.join("report/index.html")).unwrap();
    assert!(html.contains("1 left out"), "{html}");
    let row = &html[html.find("data-name=\"mirror\"").unwrap()..];
    let row = &row[..row.find("</tr>").unwrap()];
    assert!(
        row.contains("left out of the library") && row.contains("did not converge"),
        "{row}"
    );
    for name in ["gold", "film"] {
        assert!(
            b.join(format!("report/{name}-sphere.png")).is_file(),
            "{name}"
        );
    }
    let film = &html[html.find("data-name=\"film\"").unwrap()..];
    let film = &film[..film.find("</tr>").unwrap()];
    assert!(film.contains("&#9888;"));
    // The methods each angle used, and no path of this machine (issue 71): the samples
    // and the batch folder are named relative to the page.
    assert!(film.contains("methods: "), "{film}");
    for abs in [r.as_str(), d.to_str().unwrap()] {
        assert!(!html.contains(abs), "{abs} in the page");
    }
    assert!(film.contains("sample thin-film-600nm.toml"), "{film}");
}

/// A batch unit runs at its plan's trees: at 8 trees the film's transform cannot hold the
/// rays' power (an auto run alone would raise its trees), yet its units keep 8, so the
/// material's units merge into the plan's run, and its cells that cannot hold take rays
/// with the warning that says so.
#[test]
fn batch_units_do_not_raise_their_trees() {
    let d = scratch("batch-no-raise");
    let p = plan(&d, 8);
    let b = d.join("b");
    one_process(&p, &b);
    let unit = b.join("units").join("thin-film-600nm").join("0000.gsa");
    let acc = goniospec::accumulate::file::Accumulator::read(&unit).unwrap();
    assert_eq!(acc.header.rays_asked, Some(8));
    let w = &acc.header.warnings;
    assert!(
        w.iter().any(|w| w.contains("so those cells took rays")),
        "{w:?}"
    );
    assert!(!w.iter().any(|w| w.contains("raised its trees")), "{w:?}");
}

/// A material name that would make a hidden file or one read as an option is refused,
/// saying which (issue 74: '-rf' wrote out/-rf.gsa; the '.' refusal did not say what was
/// wrong).
#[test]
fn names_starting_with_a_dot_or_a_dash_are_refused_by_name() {
    let d = scratch("batch-names");
    for (name, word) in [
        ("-rf", "must not start with '-'"),
        (".x", "must not start with '.'"),
    ] {
        let p = d.join(format!("plan{name}.toml"));
        std::fs::write(
            &p,
            format!(
                "[defaults]\ntheta_i = [0]\nrays = 4\n[[material]]\nsample = \"{}/meshes/rough-gold.toml\"\nname = \"{name}\"\n",
                root().display()
            ),
        )
        .unwrap();
        let out = d.join(format!("lib{name}"));
        let (code, _, err) = goniospec(&[
            "batch",
            "plan",
            p.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{name}");
        assert!(err.contains(word), "{name}: {err}");
        assert!(!out.exists());
    }
}
