#!/bin/sh
# Every figure of the README gallery, one documented command each.  From the
# repository root, after `make setup`:   sh docs/make_gallery.sh   (or `make gallery`)
# Results go to $OUT (default results/gallery); the figures shown in the README are
# copied to docs/gallery/.
set -eu
R=${RUBCOSIM:-.venv/bin/rubcosim}
OUT=${OUT:-results/gallery}
Q=--no-progress

# 1. Single-DOF grazing: linear impact oscillator x'' + 0.1 x' + x = F cos 2t, barrier at 1;
#    the non-impacting orbit grazes at F = sqrt(9.04), then impacts with a square-root law
$R sweep scenarios/impact_duffing.toml --set oscillator.cubic_stiffness=0.0 \
    --set oscillator.x0=0.0 --param oscillator.forcing_amplitude=2.6:3.6:150 \
    --periods 40 --discard 200 --grazing $Q --out "$OUT/single_dof_grazing"

# 2. Symmetric rigid stops: bifurcation diagram over the forcing frequency, both directions
$R sweep scenarios/impact_oscillator_symmetric.toml \
    --param oscillator.forcing_frequency=0.8:2.4:200 --direction both \
    --periods 40 --discard 300 $Q --out "$OUT/symmetric_stops"

# 3. Rigid stator, centred: impacts, chattering, then synchronous full annular rub
$R run scenarios/jeffcott_rigid_stator.toml --out "$OUT/rigid_centred"

# 4. Rigid stator offset by 0.4 clearance: bifurcation diagram over the speed
#    (periodic impacting motions, chaos between about 300 and 370 rad/s, full rub above)
$R sweep scenarios/jeffcott_offset_rigid_stator.toml --param rotor.speed=250:700:200 \
    --periods 40 --discard 100 $Q --out "$OUT/rigid_offset"

# 5. Two-mass rotor on oil-film bearings with rub
$R run scenarios/two_mass_oilfilm_rub.toml --out "$OUT/oilfilm_rub"

# 6. Elastic casing with its own mass
$R run scenarios/jeffcott_elastic_casing.toml --out "$OUT/elastic_casing"

# 7. Coexisting attractors of the one-sided impact Duffing oscillator (Feng & Yang):
#    basins by generalized cell mapping, 200 x 200 cells x 16 samples
$R basins scenarios/impact_duffing.toml --grid 200x200 --samples 16 --region=-3:1,-6:6 \
    $Q --out "$OUT/duffing_basins"

# 8. Chaos control by delayed feedback: the same rotor without control (chaotic), then
#    with velocity feedback switched on after 100 periods (period 1, force dies away)
$R run scenarios/jeffcott_chaos_control.toml --set controller.gain=0.0 \
    --out "$OUT/chaos_uncontrolled"
$R run scenarios/jeffcott_chaos_control.toml --out "$OUT/chaos_control"

# 9. Chaos control studies of the rigid and the penalty stator: the uncontrolled Lyapunov
#    spectrum, the unstable period-1 target orbit (Newton, Floquet multipliers), then 8
#    switch-on times per gain and ETDAS memory R, each run judged caught or not
$R control-study scenarios/jeffcott_chaos_control.toml --switch-on 1.528:1.9:8 \
    --gains 300,400,500,600,700,800,1000,1500 --memory 0,0.3,0.6 --periods 150 \
    $Q --out "$OUT/study_chaos_control"
$R control-study scenarios/jeffcott_penalty_chaos_control.toml --switch-on 1.528:1.9:8 \
    --gains 300,400,500,600,700,800,1000,1500 --memory 0,0.3,0.6 --periods 150 \
    $Q --out "$OUT/study_penalty_chaos_control"

G=docs/gallery
mkdir -p "$G"
cp "$OUT/single_dof_grazing/bifurcation.png" "$G/single_dof_grazing.png"
cp "$OUT/single_dof_grazing/grazing.png" "$G/single_dof_sqrt_law.png"
cp "$OUT/symmetric_stops/bifurcation.png" "$G/symmetric_stops.png"
cp "$OUT/rigid_centred/orbit.png" "$G/rigid_centred_orbit.png"
cp "$OUT/rigid_offset/bifurcation.png" "$G/rigid_offset_sweep.png"
cp "$OUT/oilfilm_rub/orbit.png" "$G/oilfilm_rub_orbit.png"
cp "$OUT/elastic_casing/timeseries.png" "$G/elastic_casing.png"
cp "$OUT/duffing_basins/basins.png" "$G/duffing_basins.png"
cp "$OUT/chaos_control/timeseries.png" "$G/chaos_control.png"
cp "$OUT/chaos_uncontrolled/poincare.png" "$G/chaos_poincare_without_control.png"
cp "$OUT/chaos_control/poincare.png" "$G/chaos_poincare_with_control.png"
cp "$OUT/study_chaos_control/success.png" "$G/control_study_rigid.png"
cp "$OUT/study_penalty_chaos_control/success.png" "$G/control_study_penalty.png"
echo "gallery figures in $G"
