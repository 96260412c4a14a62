#!/usr/bin/env bash
# Copy the gallery (docs/gallery.md)'s figures (SVG; heat maps PNG) from the run directories into docs/gallery/.
# The runs themselves are made by the commands listed in docs/gallery.md.
set -euo pipefail
cd "$(dirname "$0")/.."
out=docs/gallery
mkdir -p "$out"
copy() { # copy SRC NAME [EXT]: SRC.EXT -> docs/gallery/NAME.EXT (default svg), if the run exists
  local ext=${3:-svg}
  if [ -f "$1.$ext" ]; then cp "$1.$ext" "$out/$2.$ext"; echo "$out/$2.$ext"; else echo "skip $1 (not run)"; fi
}
copy runs/demo/compare/velocity_norm demo_velocity_norm
copy runs/demo/compare/velocity_correlation demo_velocity_correlation
copy runs/demo/compare/velocity_slice demo_velocity_slice png  # heat maps: PNG is smaller
copy runs/dilute/compare/velocity_norm dilute_velocity_norm
copy runs/dilute/compare/velocity_correlation dilute_velocity_correlation
copy runs/dilute/compare/velocity_slice dilute_velocity_slice png
copy runs/paper-dilute/compare/velocity_norm paper_dilute_velocity_norm
copy runs/paper-dilute/compare/velocity_correlation paper_dilute_velocity_correlation
copy runs/paper-dilute/compare/saturated_norm paper_dilute_saturated_norm
for f in c n Q; do copy runs/paper-dilute/compare/correlation_$f paper_dilute_correlation_$f; done
copy runs/paper-dilute/compare/msd paper_dilute_msd
copy runs/paper-dilute/compare/velocity_slice paper_dilute_velocity_slice png
copy runs/paper-dilute/compare/series paper_dilute_series csv
# The series grown on GPU nodes, drawn from the members' compact products (docs/gallery/paper-dilute/)
# with the table's other rows: `motile compare docs/gallery/paper-dilute/L75
# docs/gallery/paper-dilute/mf128 --table docs/gallery/paper_dilute_series.csv --out runs/paper-dilute-series`.
for f in velocity_norm saturated_norm velocity_correlation_normalised orientation msd; do
  copy runs/paper-dilute-series/$f paper_dilute_series_$f
done
copy runs/fidelity/pair_fidelity pair_fidelity
copy runs/onset-0.625/onset onset_0.625
copy runs/onset-0.625/onset_frequency onset_0.625_frequency
for L in 16 24 32; do copy runs/study-hydro-L$L/study_hydrodynamics study_hydrodynamics_L$L; done
copy runs/study-dilute-dt/study_dt study_dt_paper_dilute
copy runs/study-nodes-paper-dilute/study_quadrature_points study_quadrature_points_paper_dilute
copy runs/concentrated/compare/correlation_Q concentrated_correlation_Q
copy runs/concentrated/compare/msd concentrated_msd
copy runs/concentrated/compare/orientation concentrated_orientation
copy runs/onset/onset onset
for k in sum_tolerance quadrature_points hydrodynamics dt meanfield_dt grid closure_degree; do
  copy runs/study/study_$k study_$k
done
copy runs/study_concentrated/study_dt study_dt_concentrated
# The concentrated series (`motile run paper-concentrated --only L6 --only L8 --only L12 --only mf32`).
for f in norm_scaling velocity_norm velocity_correlation correlation_Q msd orientation; do
  copy runs/paper-concentrated/compare/$f paper_concentrated_$f
done
copy runs/paper-concentrated/compare/particle_statistics paper_concentrated_series csv
for f in c n Q; do
  copy runs/paper-concentrated/compare/pair_correlation_$f paper_concentrated_pair_correlation_$f
done
copy runs/paper-concentrated/compare/pair_correlations paper_concentrated_pair_correlations csv
# Both volume fractions side by side: `motile compare runs/paper-concentrated/{L6,L8,L12}
# docs/gallery/paper-dilute/L75 --out runs/fractions`.
for f in msd orientation; do copy runs/fractions/$f paper_fractions_$f; done
copy runs/stability/stability_particle stability_particle
copy runs/stability/stability_meanfield stability_meanfield_D1e-4
copy runs/stability_D1e-3/stability_meanfield stability_meanfield_D1e-3
