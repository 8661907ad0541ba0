"""Random road profiles after ISO 8608, as written in the paper (eq. 2-6).

r(s) = sum_i A_i sin(w_i s - phi_i), with w_i evenly spaced from w1 = 0.02 pi to wM = 6 pi rad/m,
Phi(w) = Phi(w0) (w / w0)^-2, Phi(w0) = 2^k 1e-6 (k = 0, 2, ..., 8 for classes A..E), w0 = 1 rad/m.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Sequence

import numpy as np

from hybrid_sysid.core.checks import bad, check_dt, check_int, check_positive
from hybrid_sysid.core.options import ROAD_CLASSES

_CLASS_EXPONENT = {c: 2 * i for i, c in enumerate(ROAD_CLASSES)}  # A: k=0 ... E: k=8
OMEGA_0 = 1.0
OMEGA_1 = 0.02 * np.pi
OMEGA_M = 6.0 * np.pi


def check_classes(road_classes: Sequence[str]) -> list[str]:
    """The road classes as a list; the one range check of ``road_classes`` (data.spec calls it too)."""
    classes = list(road_classes)
    if any(c not in _CLASS_EXPONENT for c in classes):
        bad("road_classes", classes, f"each class must be one of {', '.join(ROAD_CLASSES)}")
    return classes


def check_drive(speed: float | None = None, n_waves: int | None = None) -> None:
    """The one range check of the speed and of the number of waves of a road (data.spec calls it too); None: not
    checked."""
    if speed is not None:
        check_positive("speed", speed, "m/s")
    if n_waves is not None:
        check_int("n_waves", n_waves, 2)


def wave_numbers(n_waves: int = 300) -> np.ndarray:
    """The paper's w_i = w1 + (i - 1) dw, i = 1..M, dw = (wM - w1) / (M - 1), in rad/m."""
    check_drive(n_waves=n_waves)
    return np.linspace(OMEGA_1, OMEGA_M, n_waves)


def class_psd(road_class: str) -> float:
    """Phi(w0) = 2^k 1e-6 m^3 for the class (eq. 5)."""
    (c,) = check_classes([road_class])
    return 2.0 ** _CLASS_EXPONENT[c] * 1e-6


def wave_amplitudes(road_class: str, n_waves: int = 300) -> np.ndarray:
    """A_i for one class: eq. 3, sqrt(Phi dw / pi). (The form common elsewhere, sqrt(2 Phi dw), gives a road RMS
    sqrt(2 pi), about 2.5 times, larger: docs/physics.md, "Road".)"""
    w = wave_numbers(n_waves)
    dw = w[1] - w[0]
    phi = class_psd(road_class) * (w / OMEGA_0) ** -2
    return np.sqrt(phi * dw / np.pi)


def road_amplitudes(road_classes: Sequence[str], n_waves: int = 300) -> np.ndarray:
    """A_i of every road, (n_roads, n_waves), one road per class letter."""
    classes = check_classes(road_classes)
    return np.stack([wave_amplitudes(c, n_waves) for c in classes]) if classes else np.empty((0, n_waves))


def road_phases(n_roads: int, n_waves: int, rng: np.random.Generator) -> np.ndarray:
    """phi_i of every road, uniform on [0, 2 pi): (n_roads, n_waves), the draw ``road_profiles`` makes."""
    return rng.uniform(0.0, 2.0 * np.pi, size=(n_roads, n_waves))


def road_profiles(
    road_classes: Sequence[str],
    n_steps: int,
    dt: float,
    speed: float,
    n_waves: int = 300,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Road displacement r(t_k), t_k = k dt, s = speed * t, one road per class letter: (n_roads, n_steps).

    Phases are uniform on [0, 2 pi), drawn from ``rng``. Every road shares one sine/cosine basis over
    (steps, waves), so sin(w s - phi) = sin(w s) cos(phi) - cos(w s) sin(phi) becomes two matrix products.

    Parameters
    ----------
    road_classes : sequence of str
        One ISO 8608 class letter, A to E, per road (eq. 5).
    n_steps : int
        Samples per road, >= 1.
    dt : float
        The step in s, > 0.
    speed : float
        The constant speed v in m/s, > 0 (eq. 6).
    n_waves : int
        M, the sines per road (eq. 2).
    rng : numpy.random.Generator, int or None
        The phases' generator, or its seed.

    Returns
    -------
    numpy.ndarray
        (n_roads, n_steps) float64 displacements in m.

    Raises
    ------
    ConfigError
        An unknown class or a value out of range, naming it.
    """
    classes = check_classes(road_classes)
    check_int("n_steps", n_steps, 1)
    check_dt(dt)
    check_drive(speed, n_waves)
    rng = np.random.default_rng(rng)
    phases = road_phases(len(classes), n_waves, rng)

    base = wave_amplitudes("A", n_waves)  # class A; each class step doubles the amplitude
    scale = np.array([2.0 ** (_CLASS_EXPONENT[c] / 2) for c in classes])
    s = speed * dt * np.arange(n_steps)
    arg = np.outer(s, wave_numbers(n_waves))  # (steps, waves)
    with ThreadPoolExecutor(1) as pool:  # numpy releases the GIL: sin on a second core while cos runs here
        sin_job = pool.submit(np.sin, arg)
        cos_basis = np.cos(arg)
        sin_basis = sin_job.result()
    coef_sin = base * np.cos(phases)  # (roads, waves)
    coef_cos = base * np.sin(phases)
    road = coef_sin @ sin_basis.T - coef_cos @ cos_basis.T
    return road * scale[:, None]
