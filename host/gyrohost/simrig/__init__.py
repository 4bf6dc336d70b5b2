"""Simulated rig: pseudo-terminal device emulators and fault injection.

Submodules: ``pty_link`` (pty pair and the emulator's I/O loop), ``arrivals`` (the times bytes
arrive at a pty, stamped by a child process), ``faults`` (byte-stream fault
filter), ``imu_emu`` (WitMotion BWT61CL), ``servo_emu`` (Dynamixel MX-12W bus), ``wheel_emu``
(wheel board, protocol v2), ``simavr`` (the real firmware in the simavr harness as the wheel
board), ``truth`` (the dynamics model as the truth), ``sim``
(:class:`~gyrohost.simrig.sim.SimulatedRig`: truth and the three devices; docs/rig.md), ``process``
(the simulated rig in a child process, for runs in real time).
"""
