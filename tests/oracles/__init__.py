"""Test oracles: the independent references the tests and the bench scripts measure the package
against, kept out of the installed package. closed_forms: capacitances in closed form;
sigma_delta_reference: the numpy sigma-delta loop; gyro_reference: the gyroscope's sense loop and its
noise reading; bem_reduced: the reduced BEM problem;
lateral_comb: the comb of the comb tests and its pull-in readings; testbench: the simulator
benches (ngspice releases, PULSE drives, a bench around one instance, the solve_ivp transient);
va_scan: the scan of Verilog-A text for the openvaf-r miscompile; process_balance: the pull-in and
the gravity balance voltage of the process-parameter tests; process_cases: the process tests'
structure texts and etch re-runs; crab_legs: the proof mass on crab legs that the process,
inertial and sweep tests and benches share; process_forms: the piston's dg runs in its emitted forms;
fastcap_guarded: the guarded layered electrode of the FastCap dielectric tests; sigma_delta_vacask:
the VACASK loop test's run and its independent integration. fmu_process: the FMU's process parameters
against closed forms and ngspice. Imports of the package inside
are absolute (`netgen.`), of each other relative, so that bench/support.py can load the folder
by its path."""
