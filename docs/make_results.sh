#!/usr/bin/env bash
# Re-run every sweep behind docs/results/ (about thirteen hours on two CPU cores, ten of them experiment=anchored;
# the sweeps the readings rest on first), then regenerate the pages.
# With the sweeps already on disk, only the last command is needed.
# docs/figures/main_job.png, the README's figure, is not written here: it is figures/robustness.png of a run of the
# README's first command (hybrid-sysid experiment=robustness), kept with that run's table in docs/results_notes.md
# ("The main job (README)").
set -euo pipefail
cd "$(dirname "$0")/.."
out=outputs/multirun
hybrid-sysid experiment=robustness hydra.sweep.dir=$out/robustness
hybrid-sysid experiment=robustness data.seat_spread=0.3 objective=labelled,hybrid,combined,hybrid_bandpass,label_free \
  hydra.sweep.dir=$out/robustness_spread
hybrid-sysid experiment=field hydra.sweep.dir=$out/field
hybrid-sysid experiment=transfer hydra.sweep.dir=$out/transfer
hybrid-sysid experiment=noise_robust hydra.sweep.dir=$out/noise_robust
hybrid-sysid experiment=best hydra.sweep.dir=$out/best
hybrid-sysid experiment=ablations data.measurement=paper noise.train_std=0.0 hydra.sweep.dir=$out/ablations_measurement
hybrid-sysid experiment=ablations data.measurement=consistent noise.train_std=0.01 hydra.sweep.dir=$out/ablations_trainnoise
hybrid-sysid experiment=baselines hydra.sweep.dir=$out/baselines
hybrid-sysid experiment=baselines data.measurement=paper hydra.sweep.dir=$out/baselines_paper
hybrid-sysid experiment=paper hydra.sweep.dir=$out/paper
hybrid-sysid experiment=noise_robust data.measurement=paper noise.train_std=0.01 \
  objective=labelled,hybrid_bandpass,hybrid_eiv hydra.sweep.dir=$out/noise_robust_paper
# the rest of that grid (its "All rows" table merges the three: merge= in the report below)
hybrid-sysid experiment=noise_robust data.measurement=paper noise.train_std=0.0 hydra.sweep.dir=$out/noise_robust_paper_clean
hybrid-sysid experiment=noise_robust data.measurement=paper noise.train_std=0.01 objective=hybrid \
  hydra.sweep.dir=$out/noise_robust_paper_hybrid
hybrid-sysid experiment=tuned hydra.sweep.dir=$out/tuned   # pip install -e ".[search]"
hybrid-sysid experiment=anchored hydra.sweep.dir=$out/anchored
hybrid-sysid experiment=anchored_clean hydra.sweep.dir=$out/anchored_clean
hybrid-sysid experiment=compare objective=labelled,hybrid,label_free,cross_segment hydra.sweep.dir=$out/compare
hybrid-sysid-report $out/robustness $out/best $out/ablations_measurement $out/ablations_trainnoise $out/baselines \
  $out/paper $out/transfer $out/field $out/robustness_spread $out/noise_robust $out/baselines_paper $out/noise_robust_paper \
  $out/tuned $out/anchored $out/anchored_clean $out/compare exclude='*/search/*' results=docs/results notes=docs/results_notes.md reproduction=true \
  merge=$out/noise_robust_paper,$out/noise_robust_paper_clean,$out/noise_robust_paper_hybrid
