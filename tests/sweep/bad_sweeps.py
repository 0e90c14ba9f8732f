"""Generated bad sweep files, by class: each case is (class, file bytes, the key its message must
name). Every one is a mistake a user makes (or an attacker tries) that `netgen sweep` must refuse
before anything runs, with the file, the key and a fix (tests/sweep/test_sweep_files.py)."""

from __future__ import annotations

HEAD = '[sweep]\nfigure = "z.noise_floor_db_per_hz"\n'
FIXED = "[fixed]\ncycles = 128\nrigid_only = true\n"
PARAM = '[[parameters]]\nname = "ts"\nvalues = ["1 us", "2 us"]\n'
GOOD = HEAD + FIXED + PARAM

# per testbench parameter: values that must be refused (TOML literals)
BAD_VALUES: dict[str, list[str]] = {
    "ts": ["0", "-1e-6", '"1 uV"', '"abc"', "inf", "nan", "1e300", "true", "[1e-6]", "{a = 1}", '"1e-15 s"', '"2 s"'],
    "cycles": ["32", "1.5", '"128"', "true", "-1", "1_000_000_000_000", "inf"],
    "skip": ["-1", "1.5", "100", '"2"'],
    "lead": ["inf", "nan", '"x"', "true", "1e300", "-10.5", "11"],
    "density": ["0", "1", "1.5", "-0.5", '"half"'],
    "sense_ratio": ["0", "-1", "inf", "1e300"],
    "full_scale": ["0", "-1", "1e300", "nan"],
    "dither": ["-0.1", "1.5", '"x"', "inf"],
    "tone": [
        '"z:0.02"',
        '"z:a:1000"',
        '"nope:1:1000"',
        '"z:0.02:-5"',
        '"z:0.02:0"',
        '"z:inf:1000"',
        '"z:nan:1000"',
        '"z:0.02:1e12"',
        "5",
        '":1:1000"',
        '"z:0.02:1000:5"',
        '"m1:0.02:1000"',
        '"z:0.02:nan"',
        "true",
    ],
    "rigid_only": ['"yes"', "1", "[true]"],
    "simulator": ['"spice3"', '""', "1", '"NGSPICE"', '"ngspice;rm"', '["ngspice"]'],
    "reltol": ["0.1", "0", "-1", '"x"', "1e-9", "nan"],
}
TONE = 'tone = "z:0.02:2000"\n'


def _fixed(name: str, value: str, extra: str = "") -> str:
    return HEAD + FIXED + extra + f"{name} = {value}\n" + PARAM


def _swept(name: str, value: str, extra: str = "") -> str:
    ok = '"z:0.02:2000"' if name == "tone" else {"simulator": '"ngspice"', "rigid_only": "true"}.get(name, "")
    first = f"{ok}, " if ok else ""
    return HEAD + FIXED + extra + f'[[parameters]]\nname = "{name}"\nvalues = [{first}{value}]\n'


def cases() -> list[tuple[str, bytes, str]]:
    """(class, file content, key the message names) for every generated bad sweep file."""
    out: list[tuple[str, str | bytes, str]] = []
    add = out.append
    # --- file and TOML syntax
    add(("file", b"\xff\xfe[sweep]\n", "file"))
    add(("file", GOOD.encode("latin-1") + b"# caf\xe9\n", "file"))
    add(("file", b"\x00\x01\x02binary\x00", "file"))
    add(("file", b"", "parameters"))
    add(("file", b"# only a comment\n", "parameters"))
    for text in [
        "[sweep\n",
        "x = \n",
        'figure = "a"\nfigure = "b"\n',
        'mode = "grid\n',
        "[[parameters]\n",
        "[sweep]\nmode = grid\n",
        HEAD + HEAD,
        "parameters = [1,\n",
    ]:
        add(("toml", text, "TOML syntax"))
    # --- tables
    add(("tables", GOOD + "[extra]\na = 1\n", "extra"))
    add(("tables", "sweep = 1\n" + PARAM, "sweep"))
    add(("tables", "fixed = 1\n" + PARAM, "fixed"))
    add(("tables", "parameters = 1\n", "parameters"))
    add(("tables", "parameters = []\n", "parameters"))
    add(("tables", "parameters = [1, 2]\n", "parameters"))
    add(("tables", HEAD + FIXED, "parameters"))
    # --- [sweep] keys
    for key, value, where in [
        ("figur", '"x"', "sweep.figur"),
        ("figure", '"z.noise_flor"', "sweep.figure"),
        ("figure", "1", "sweep.figure"),
        ("figure", '["z.snr_db"]', "sweep.figure"),
        ("mode", '"grd"', "sweep.mode"),
        ("mode", "1", "sweep.mode"),
        ("mode", '["grid"]', "sweep.mode"),
        ("samples", "0", "sweep.samples"),
        ("samples", "-1", "sweep.samples"),
        ("samples", "1.5", "sweep.samples"),
        ("samples", "true", "sweep.samples"),
        ("samples", '"2"', "sweep.samples"),
        ("seed", "-1", "sweep.seed"),
        ("seed", "1.5", "sweep.seed"),
        ("seed", '"a"', "sweep.seed"),
        ("seed", "inf", "sweep.seed"),
        ("retries", "-1", "sweep.retries"),
        ("retries", "true", "sweep.retries"),
        ("retries", "1000", "sweep.retries"),
        ("plots", '"yes"', "sweep.plots"),
        ("plots", "1", "sweep.plots"),
        ("x", '"cycles"', "sweep.x"),
        ("x", "5", "sweep.x"),
        ("timeout", "0", "sweep.timeout"),
        ("timeout", "-1", "sweep.timeout"),
        ("timeout", '"abc"', "sweep.timeout"),
        ("timeout", "inf", "sweep.timeout"),
        ("timeout", '"1 m"', "sweep.timeout"),
        ("timeout", "nan", "sweep.timeout"),
    ]:
        add(("sweep", f"[sweep]\n{key} = {value}\n" + FIXED + PARAM, where))
    # --- testbench values, fixed and swept
    for name, values in BAD_VALUES.items():
        for v in values:
            extra = TONE if name in ("tone_amplitude", "tone_freq") else ""
            if name == "cycles":
                fixed = HEAD + "[fixed]\nrigid_only = true\n" + f"cycles = {v}\n" + PARAM
            elif name == "rigid_only":
                fixed = HEAD + "[fixed]\ncycles = 128\n" + f"rigid_only = {v}\n" + PARAM
            else:
                fixed = _fixed(name, v, extra)
            add(("fixed value", fixed, f"fixed.{name}"))
            if name in ("cycles", "rigid_only"):
                continue
            add(("swept value", _swept(name, v, extra), "parameters[0].values"))
    for v in ["inf", '"x"', "nan", "[1]"]:
        add(("fixed value", _fixed("tone_amplitude", v, TONE), "fixed.tone_amplitude"))
    for v in ["0", "-1", '"1 m"', "1e12", "inf"]:
        add(("fixed value", _fixed("tone_freq", v, TONE), "fixed.tone_freq"))
    # --- structure parameters
    for name, value, where in [
        ("structure.electrodes.gapp", '"3 um"', "structure.electrodes.gapp"),
        ("structure.nokey.x", "1", "structure.nokey.x"),
        ("structure.electrodes[9].gap", '"3 um"', "structure.electrodes[9].gap"),
        ("structure.electrodes.gap", "[1, 2]", "structure.electrodes.gap"),
        ("structure.electrodes.gap", "{a = 1}", "structure.electrodes.gap"),
        ("structure.electrodes.gap", '"-3 um"', "structure.electrodes.gap"),
        ("structure.electrodes.gap", '"3 uV"', "structure.electrodes.gap"),
        ("structure.electrodes.gap", "0", "structure.electrodes.gap"),
        ("structure.conductor.radius", '"0 m"', "structure.conductor.radius"),
        ("structure.conductor.density", '"-1 kg/m^3"', "structure.conductor.density"),
        ("structure.fem.refine", "-1", "structure.fem.refine"),
        ("structure.coordinates.modes", '"many"', "structure.coordinates.modes"),
        ("structure..gap", '"3 um"', "structure..gap"),
        ("structure.electrodes[x].gap", '"3 um"', "structure.electrodes[x].gap"),
        ("structure.description", '"a\\n.control\\nshell touch x\\n.endc"', "structure.description"),
        ("structure.name", '"bad name; rm"', "structure.name"),
    ]:
        add(
            (
                "structure value",
                HEAD + FIXED + f'"{name}" = {value}\n' + PARAM
                if "[" in name or ".." in name
                else HEAD + FIXED + PARAM + f'[[parameters]]\nname = "{name}"\nvalues = [{value}]\n',
                where,
            )
        )
    # --- parameter entries
    P = HEAD + FIXED + "[[parameters]]\n"
    for body, where in [
        ("name = 5\nvalues = [1]\n", "parameters[0].name"),
        ('name = "ts"\nvalue = ["1 us"]\n', "parameters[0].value"),
        ('name = "ts"\n', "parameters[0]"),
        ('name = "ts"\nvalues = ["1 us"]\nstart = "1 us"\n', "parameters[0]"),
        ('name = "ts"\nvalues = "1 us"\n', "parameters[0].values"),
        ('name = "ts"\nvalues = []\n', "parameters[0].values"),
        ('name = "tss"\nvalues = [1e-6]\n', "parameters[0].name"),
        ('name = ""\nvalues = [1e-6]\n', "parameters[0].name"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = 0\n', "parameters[0].num"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = 1.5\n', "parameters[0].num"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = true\n', "parameters[0].num"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = 1_000_000_000\n', "parameters[0].num"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = 1_000_000_000_000_000\n', "parameters[0].num"),
        ('name = "ts"\nstart = "1 us"\nnum = 3\n', "parameters[0].stop"),
        ('name = "ts"\nstart = inf\nstop = 2e-6\nnum = 3\n', "parameters[0].start"),
        ('name = "ts"\nstart = "x"\nstop = 2e-6\nnum = 3\n', "parameters[0].start"),
        ('name = "ts"\nstart = "1 us"\nstop = "2 us"\nnum = 3\nscale = "exp"\n', "parameters[0].scale"),
        ('name = "ts"\nstart = 0\nstop = 2e-6\nnum = 3\nscale = "log"\n', "parameters[0].start"),
        ('name = "ts"\nstart = -1e-6\nstop = 2e-6\nnum = 3\n', "parameters[0]"),
        ('name = "simulator"\nstart = 1\nstop = 2\nnum = 2\n', "parameters[0]"),
        ('name = "tone"\ndistribution = "normal"\nmean = 1\nstd = 1\n', "parameters[0]"),
        ('name = "rigid_only"\nstart = 0\nstop = 1\nnum = 2\n', "parameters[0]"),
        ('name = "ts"\ndistribution = "gauss"\nmean = 1e-6\nstd = 1e-8\n', "parameters[0].distribution"),
        ('name = "ts"\ndistribution = 1\nmean = 1e-6\nstd = 1e-8\n', "parameters[0].distribution"),
        ('name = "cycles"\ndistribution = "normal"\nmean = 128\nstd = 8\n', "parameters[0].distribution"),
        ('name = "ts"\ndistribution = "normal"\nmean = 1e-6\nstd = -1e-8\n', "parameters[0]"),
        ('name = "ts"\ndistribution = "uniform"\nlow = 2e-6\nhigh = 1e-6\n', "parameters[0]"),
        ('name = "ts"\ndistribution = "normal"\nstd = 1e-8\n', "parameters[0].mean"),
        ('name = "ts"\ndistribution = "normal"\nmean = "1 us"\nstd = "1 us"\n', "parameters[0]"),
        ('name = "density"\ndistribution = "uniform"\nlow = 0.5\nhigh = 1.5\n', "parameters[0]"),
        ('name = "reltol"\ndistribution = "normal"\nmean = 1e-3\nstd = 1e-2\n', "parameters[0]"),
        (
            'name = "structure.electrodes.gap"\ndistribution = "normal"\nmean = "3 um"\nstd = "3 um"\n',
            "structure.electrodes.gap",
        ),
        ('name = "structure.electrodes.gap"\nstart = "-1 um"\nstop = "3 um"\nnum = 3\n', "structure.electrodes.gap"),
        ('name = "cycles"\nstart = 16\nstop = 128\nnum = 3\n', "parameters[0]"),
        ('name = "ts"\nvalues = ["1 us", "1 us"]\nnum = 2\n', "parameters[0]"),
    ]:
        if "distribution" in body:  # 50 draws: some fall outside the range
            add(("parameter", HEAD + "samples = 50\n" + FIXED + "[[parameters]]\n" + body, where))
            continue
        add(("parameter", P + body, where))
    # --- combinations
    TS = '[[parameters]]\nname = "ts"\nvalues = ["1 us", "2 us"]\n'
    MC = '[[parameters]]\nname = "lead"\ndistribution = "uniform"\nlow = 0.7\nhigh = 0.9\n'
    for text, where in [
        (HEAD + FIXED + TS + TS, "parameters"),
        (HEAD + "[fixed]\ncycles = 128\nts = 1e-6\n" + TS, "fixed.ts"),
        ('[sweep]\nmode = "zip"\n' + FIXED + TS + '[[parameters]]\nname = "lead"\nvalues = [0.7]\n', "sweep.mode"),
        ('[sweep]\nmode = "zip"\n' + FIXED + MC, "sweep.mode"),
        ('[sweep]\nmode = "zip"\nsamples = 4\n' + FIXED + MC, "sweep.mode"),
        ("[sweep]\nsamples = 3\n" + FIXED + TS, "sweep.samples"),
        (HEAD + FIXED + '[[parameters]]\nname = "tone_amplitude"\nvalues = [0.01, 0.02]\n', "tone_amplitude"),
        (HEAD + FIXED + '[[parameters]]\nname = "tone_freq"\nvalues = [1000, 2000]\n', "tone_freq"),
        (HEAD + FIXED + "tone_freq = 1000\n" + TS, "tone_freq"),
        (HEAD + FIXED + TONE + '[[parameters]]\nname = "tone_freq"\nvalues = [1000, 1e9]\n', "tone_freq"),
        (
            HEAD + FIXED + 'tone = "z:0.02:400000"\n' + '[[parameters]]\nname = "ts"\nvalues = ["1 us", "2 us"]\n',
            "tone",
        ),
        (HEAD + "[fixed]\ncycles = 128\n" + 'tone = "m1:0.02:1000"\n' + "rigid_only = true\n" + TS, "fixed.tone"),
        ('[sweep]\nx = "lead"\n' + FIXED + TS, "sweep.x"),
    ]:
        add(("combination", text, where))
    # --- sizes: refused before any list of runs is made
    R = '[[parameters]]\nname = "{n}"\nstart = {a}\nstop = {b}\nnum = {k}\n'
    for text, where in [
        (
            HEAD
            + FIXED
            + R.format(n="ts", a=1e-6, b=2e-6, k=1000)
            + R.format(n="lead", a=0.1, b=0.9, k=1000)
            + R.format(n="density", a=0.3, b=0.7, k=1000),
            "runs",
        ),
        (HEAD + FIXED + R.format(n="ts", a=1e-6, b=2e-6, k=200) + R.format(n="lead", a=0.1, b=0.9, k=200), "runs"),
        ("[sweep]\nsamples = 1000000\n" + FIXED + MC, "runs"),
        ("[sweep]\nsamples = 1000000000000\n" + FIXED + MC, "runs"),
        ("[sweep]\nsamples = 200\n" + FIXED + MC + R.format(n="ts", a=1e-6, b=2e-6, k=100), "runs"),
        ('[sweep]\nmode = "zip"\nsamples = 100000\n' + FIXED + MC + TS, "runs"),
        (HEAD + FIXED + R.format(n="ts", a=1e-6, b=2e-6, k=100000), "parameters[0].num"),
        (
            HEAD
            + FIXED
            + "".join(
                R.format(n=n, a=a, b=b, k=30)
                for n, a, b in [
                    ("ts", 1e-6, 2e-6),
                    ("lead", 0.1, 0.9),
                    ("density", 0.3, 0.7),
                    ("sense_ratio", 0.1, 0.5),
                    ("full_scale", 0.005, 0.02),
                    ("dither", 0, 0.5),
                ]
            ),
            "runs",
        ),
    ]:
        add(("size", text, where))
    return [(c, t if isinstance(t, bytes) else t.encode("utf-8"), w) for c, t, w in out]
