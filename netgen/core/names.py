"""The name policy: which names from input files (structure files, model JSON) may name a model,
an electrode or an electrode set, so that every emitted dialect reads them as the node, port or
module they are meant to be. Checked when a structure file or model JSON is read (exit 2 with the
fix); the emitters keep their own guard (netgen.emit.common.check_names,
netgen.emit.veriloga.check_identifiers).

A name must be an identifier (netgen.core.text.is_identifier) and, since SPICE is case-insensitive,
differ case-insensitively from every other electrode, electrode set and port name, and not be
- a ground name of ngspice or VACASK (0, gnd) or the plate port, case-insensitively;
- a node the emitted subcircuit or a testbench derives from a coordinate, electrode or channel
  name (xs_z, u_z, p_drive_1, ca_z, ...: any name starting with one of NODE_PREFIXES, which also
  covers the ports f_<q> and x_<q>) or a fixed node of theirs (BENCH_NODES: a_in, a_x, a_y; the rate ports w_x, w_y, w_z have the prefix w_);
- a Verilog-A / Verilog-AMS keyword, or a discipline, nature, access or analog function name the
  emitted module uses (VERILOG_A, case-sensitively, as Verilog-A reads names);
- a VACASK netlist keyword (VACASK, case-insensitively).
A model name must also not be the name of a file set a run writes into the same folder
(RUN_NAMES: sigma-delta's summary.json, spectra.npz, ...), nor a Verilog-A or VACASK keyword.
"""

from __future__ import annotations

import re

from .text import is_identifier

GROUND = frozenset({"0", "gnd"})
# node-name prefixes the emitters (netgen.emit.common, veriloga, the templates) and the
# sigma-delta testbenches (netgen.testbench.sigma_delta: ngspice, vacask, filters) derive from
# coordinate, electrode and channel names: xs_<q>, u_<q>, u<j>_<ch>, m<j>_<ch>, f_<q>, x_<q>, ...
NODE_PREFIXES = re.compile(
    r"(xs|u\d*|m\d+|n|w|p|dv2|y|yf|g|c|sg|sf|f|x|d|fcon|fel|fn|fnl|b|ca|cur|prev|drv|s|q|bit|bits|latch)_",
    re.I,
)
# fixed nodes of the subcircuit and the testbenches (templates/sigma_delta, loop.py's bit nodes)
BENCH_NODES = frozenset("a_in a_x a_y plate phs phf fb1 fb2 clk rst sprev scur sfm sfs tie bz bx by".split())
VACASK = frozenset(
    "ground global load include model subckt ends parameters control endc embed postprocess options".split()
)
# the sets and files a sigma-delta run writes into its folder (netgen.testbench.sigma_delta.cli)
RUN_NAMES = frozenset("sigma-delta sigma_delta summary bitstreams spectra coordinates".split())
VERILOG_A = frozenset(
    """
    above abs absdelay absdelta abstol access acos acosh ac_stim aliasparam always analog analysis and
    asin asinh assert assign atan atan2 atanh automatic begin branch buf bufif0 bufif1 case casex casez
    ceil cell cmos config connect connectmodule connectrules continuous cos cosh cross ddt ddt_nature ddx
    deassign default defparam design disable discipline discrete domain driver_update edge else end
    endcase endconfig endconnectrules enddiscipline endfunction endgenerate endmodule endnature endparamset
    endprimitive endspecify endtable endtask event exclude exp final_step flicker_noise floor flow for
    force forever fork from function generate genvar ground highz0 highz1 hypot idt idtmod idt_nature if
    ifnone incdir include inf initial initial_step inout input instance integer join laplace_nd laplace_np
    laplace_zd laplace_zp large last_crossing liblist library limexp ln localparam log macromodule max
    medium merged min module nand nature negedge net_resolution nmos noise_table noise_table_log nor
    noshowcancelled not notif0 notif1 or output parameter paramset pmos posedge potential pow primitive
    pull0 pull1 pulldown pullup pulsestyle_onevent pulsestyle_ondetect rcmos real realtime reg release
    repeat resolveto rnmos rpmos rtran rtranif0 rtranif1 scalared sin sinh showcancelled signed slew small
    specify specparam split sqrt string strong0 strong1 supply0 supply1 table tan tanh task time timer tran
    tranif0 tranif1 transition tri tri0 tri1 triand trior trireg unsigned use uwire vectored wait wand
    weak0 weak1 while white_noise wire wor wreal xnor xor zi_nd zi_np zi_zd zi_zp
    electrical voltage current V I
    """.split()
)


def reserved(name: str) -> str | None:
    """Why `name` cannot name an electrode or electrode set in every dialect, or None."""
    low = name.lower()
    if low in GROUND:
        return f"{name!r} is ground in ngspice (0, gnd: case-insensitive)"
    if low in BENCH_NODES:
        return f"{name!r} is a port or fixed node of the emitted subcircuit or its testbenches (case-insensitive)"
    prefix = NODE_PREFIXES.match(name)
    if prefix:
        return (
            f"{name!r} starts with {prefix.group(0)!r}, the prefix of nodes and ports the emitted "
            "subcircuit and testbenches derive from coordinate and electrode names (case-insensitive)"
        )
    return keyword(name)


def keyword(name: str) -> str | None:
    """Why `name` is a keyword of an emitted dialect (Verilog-A, VACASK), or None."""
    if name in VERILOG_A:
        return f"{name!r} is a Verilog-A keyword or a name the emitted module uses"
    if name.lower() in VACASK:
        return f"{name!r} is a VACASK netlist keyword (case-insensitive)"
    return None


def model_problem(name: str) -> str | None:
    """Why `name` cannot name a model (subcircuit, module, its files), or None."""
    if name.lower() in RUN_NAMES:
        return f"{name!r} is the name of a file set `netgen sigma-delta` writes into its folder"
    return keyword(name)


def duplicate(name: str, seen: dict[str, str]) -> str | None:
    """The earlier name equal to `name` case-insensitively (SPICE reads them as one), or None;
    records `name` in `seen` (lower case -> name)."""
    earlier = seen.get(name.lower())
    seen.setdefault(name.lower(), name)
    return earlier


def rename_fix(name: str) -> str:
    """The fix for a refused name, with a usable example (name_1, else el_name)."""
    example = next(n for n in (f"{name}_1", f"el_{name}", "drive_1") if usable(n) and model_problem(n) is None)
    return f"rename it, e.g. {example} (letters, digits, _; docs/structure-files.md, Names)"


def usable(name: object) -> bool:
    """An identifier that no dialect reserves (reserved)."""
    return is_identifier(name) and reserved(name) is None
