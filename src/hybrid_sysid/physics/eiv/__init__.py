"""Errors-in-variables maximum likelihood of the seat's (p1, p2) from windows of both noisy channels (plain numpy).

The band-passed least squares (physics.seat_fit) regresses the seat acceleration on re-integrated regressors that
carry the body channel's noise, so its p is biased towards zero as the noise grows. Here the seat's transfer
function from body acceleration U to seat acceleration S is fitted in the frequency domain with noise on both
channels (Pintelon and Schoukens, "System Identification: A Frequency Domain Approach"; Soderstrom,
"Errors-in-variables methods in system identification", Automatica 43, 2007).

The model, per window of N samples, with S_k, U_k the DFT (unnormalised, k = 0..N-1) and z_k = exp(2 pi i k / N):

    A_k S_k - B_k U_k = I_k + noise,      I_k = i0 + i1 z_k^-1 + ... + i_{m-1} z_k^-(m-1), i real

where A(z), B(z) are polynomials in z^-1 whose coefficients are affine in p: A = a0 + p1 a1 + p2 a2 and
B = p1 b1 + p2 b2. I is not an approximation: A(q) s = B(q) u holds inside the window, and the circular convolution
the DFT takes differs from it only in its first m samples, where it reaches back across the window's edge; those
m values (real) are I's coefficients. White noise of std sigma_s on the seat and sigma_b on the body samples enters
as A N_s - B N_u, whose DFT is (exactly, the convolution being circular) independent over k <= N/2 with variance
N sigma_s^2 W_k, W_k = |A_k|^2 + lambda |B_k|^2, lambda = sigma_b^2 / sigma_s^2. The negative log-likelihood of
the window, maximised over the true input (a nuisance parameter at every frequency), is then, up to a constant,

    V(p) / (2 N sigma_s^2),    V(p) = sum_k |A_k S_k - B_k U_k - I_k|^2 / W_k    (sum over the full grid)

(Parseval: the full grid's sum of |DFT|^2 is N times the time domain's sum of squares). I is eliminated by
variable projection: for given p it is the weighted least squares in its m real coefficients. Computed on the half
spectrum with the weights 1 (DC, Nyquist) and 2 (the rest), which is the same sum. lambda = 0 is output error: V is
then N times the time-domain sum of squared output errors, minimised over the free initial conditions too.

Where the rest is (plain numpy but one, each module's docstring has its part): ``model``, the models of a recording
(discrete, continuous) as transfer polynomials on the DFT's grid; ``criterion``, V and its derivatives;
``newton``, the damped Newton minimiser; ``fit``, ``fit_eiv`` with its standard errors and the MAP fit;
``faults`` and ``fault_criterion``, a recording fault fitted with p, whose criterion
``compiled_criterion`` computes with numba (imported at the first fault fit); ``bound``, ``crb_relative_std``;
``prior``, ``log_p_prior``; ``posterior``, the Bayes estimate under the simulator's exact prior
(``bayes_fit``); ``matrices``, the small matrices' algebra.
"""

from hybrid_sysid.physics.eiv.bound import crb_relative_std
from hybrid_sysid.physics.eiv.fit import P_HI, P_LO, EivFit, fit_eiv
from hybrid_sysid.physics.eiv.matrices import positive, solve_positive
from hybrid_sysid.physics.eiv.model import (
    MODELS,
    eiv_model,
    error_spectra,
    frequency_grid,
    noise_weight,
    transfer_polynomials,
    weight_coefficients,
)
from hybrid_sysid.physics.eiv.newton import MAX_ITER, TOL, minimise
from hybrid_sysid.physics.eiv.prior import log_p_prior

__all__ = [
    "MAX_ITER",
    "MODELS",
    "P_HI",
    "P_LO",
    "TOL",
    "EivFit",
    "crb_relative_std",
    "eiv_model",
    "error_spectra",
    "fit_eiv",
    "frequency_grid",
    "log_p_prior",
    "minimise",
    "noise_weight",
    "positive",
    "solve_positive",
    "transfer_polynomials",
    "weight_coefficients",
]
