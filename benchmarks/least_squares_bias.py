"""The best the hybrid objective can do: a least-squares fit of (p1, p2) from the re-integrated signals.

    python benchmarks/least_squares_bias.py

For each recording scheme (docs/design.md, "The hybrid objective and the discretisation"), road class and time
step: the worst relative error of p1 and p2 over masses {50, 100, 150, 200} kg on two roads of 6 s.
Reference: numpy's lstsq in float64.
"""

import numpy as np

from hybrid_sysid.physics import (
    QuarterCar,
    continuous_recordings,
    relative_states,
    road_amplitudes,
    road_phases,
    road_profiles,
    simulate,
    wave_numbers,
)

CAR = QuarterCar()
SCHEMES = {  # name: (recording, pairing of velocities in the seat equation)
    "paper (eq. 12 recording, eq. 22 pairing)": ("paper", "paper"),
    "consistent recording, eq. 22 pairing z'_k - y'_k": ("consistent", "paper"),
    "consistent (recording + pairing z'_k - y'_{k+1})": ("consistent", "consistent"),
    "continuous recording (exact samples), symplectic Euler + pairing z'_k - y'_{k+1}": ("continuous", "consistent"),
    "continuous recording, trapezoid rule (data.measurement=continuous)": ("continuous", "continuous"),
}


def worst_error(recording, pairing, road_class, dt):
    n = int(round(6.0 / dt))
    road = road_profiles([road_class] * 2, n, dt, 15.0, rng="ABCDE".index(road_class))
    masses = np.array([[50.0, 100.0, 150.0, 200.0]] * 2)
    if recording == "continuous":  # the same roads' phases, solved exactly between samples
        phases = road_phases(2, 300, np.random.default_rng("ABCDE".index(road_class)))
        seat, body = continuous_recordings(
            road_amplitudes([road_class] * 2),
            phases,
            wave_numbers(300) * 15.0,
            np.repeat([0, 1], 4),
            masses.ravel(),
            n,
            dt,
        )
        seat, body = seat.reshape(2, 4, n), body.reshape(2, 4, n)
    else:
        seat, body = simulate(road[:, None, :], masses, dt, measurement=recording)
    rel_vel, rel_disp = relative_states(seat, body, dt, pairing)
    worst = np.zeros(2)
    for i, j in np.ndindex(masses.shape):
        X = np.stack([-rel_vel[i, j], -rel_disp[i, j]], axis=1)
        p_hat = np.linalg.lstsq(X, seat[i, j], rcond=None)[0]
        worst = np.maximum(worst, np.abs(p_hat / np.array(CAR.parameters(masses[i, j])) - 1))
    return worst


def main():
    print("| scheme | dt | " + " | ".join(f"class {c}" for c in "ABCDE") + " |")
    print("| --- | --- |" + " --- |" * 5)
    for name, (rec, pair) in SCHEMES.items():
        for dt in (0.001, 0.005):
            cells = [worst_error(rec, pair, c, dt) for c in "ABCDE"]
            print(f"| {name} | {dt * 1e3:g} ms | " + " | ".join(f"{a:.2%} / {b:.2%}" for a, b in cells) + " |")


if __name__ == "__main__":
    main()
