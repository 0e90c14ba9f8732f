"""The vibratory-gyroscope testbench (`netgen gyro`): a behavioural drive loop holding the drive
coordinate x at its resonance with a set amplitude, the sense coordinate y closed in the sigma-delta
force-feedback loop (netgen.testbench.sigma_delta: its design, its ngspice bench and loop filters,
reused), a constant rate on the model's w_z port, and the sense bitstream demodulated with the
drive phase into rate and quadrature (analysis.py)."""
