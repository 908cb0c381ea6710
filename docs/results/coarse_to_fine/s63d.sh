#!/bin/bash
# The sixty-third session's diagnosis (README, "What costs GLINT against `3dgs` at 40 epochs of 96 x 54"): GLINT at
# today's bench preset with the prior sweep's flags (s56.sh's command: 96 x 54, 40 epochs, w_sfm_depth=0, one Dr.Jit
# thread, seed 0) and one switch, on one tuning room; decides nothing. A finished run is skipped.
#   bash docs/results/coarse_to_fine/s63d.sh ARM ROOM      (ARM: priors 3dgs copy noterms el iface copyel; ROOM: 7301-7303,
#                                                          or 9801-9803 for the check of `copy`)
# The sixty-fourth session's ladder (README, "A ladder from GLINT's interface to `3dgs`"): ARM i_el, i_copy, i_photo,
# i_cons, each the one before it and one more of 3DGS's fields, and i_3dgs, the `3dgs` method itself (the next
# step, no priors, gives 3DGS's configuration to the field); photo, nocons: the steps i_photo and i_cons alone on the
# whole of GLINT. The sixty-fifth session's prior weights (README, "The prior terms' weight at 40 epochs of 96 x 54"):
# half, quarter (RUNS/d65_<arm>). The sixty-sixth session's prior weight from the priors' agreement with SfM (README,
# "A prior weight that follows the priors' agreement with SfM"): agree_n, agree_dn (RUNS/d66_<arm>), and base (today's
# preset, no switch: RUNS/d66_base) for its second seed. SEED=K: that seed alone (--seed-ids K; run folders METHOD@seedK).
# The sixty-seventh session's free interface (README, "GLINT's glass sets over a free interface"): freesf (no prior
# term, no consistency term), free (and 3DGS's kernel) (RUNS/d67_<arm>); nocons is the ladder's arm (RUNS/d64_nocons).
# The sixty-eighth session's one-sided consistency (README, "A consistency term that moves only the normals"): cgrad
# (RUNS/d68_cgrad); cpull, cpull15: that pull scaled by the normal prior's agreement with SfM (prior_weight_ref 10 or
# 15 on the consistency alone; RUNS/d68_<arm>). The seventieth session's gpull: cpull off the glass only
# (prior_weight_where off_glass; RUNS/d70_gpull). The seventy-first session's dpull: gpull from half the run
# (prior_weight_from 0.5; RUNS/d71_dpull). The seventy-second session's hpull, qpull: gpull whose g reaches 1 at t 0.5,
# 0.25 (prior_weight_glass_t; RUNS/d72_<arm>); epull: gpull from 10/60 of the run (prior_weight_from, the whole pull
# while t forms; RUNS/d72_epull). PRINT_SWITCH=1: print the arm's switch and stop (ROOM unread).
# Code of the worktree WT (pinned at the declaring commit); rooms DATA73/rROOM or DATA98/rROOM; folder RUNS/d63_<arm>
# (the ladder's RUNS/d64_<arm>).
set -u
arm=${1:?an arm: priors 3dgs copy noterms el iface copyel half quarter base agree_n agree_dn freesf free cgrad cpull cpull15 gpull dpull hpull qpull epull, or a ladder step i_el i_copy i_photo i_cons i_3dgs}; room=${2:?a room: 7301 7302 7303}
methods=glint; tag=d63
case $arm in
  priors) switch=""; methods=priors ;;                              # the renders' check: no training
  3dgs) switch=""; methods=3dgs ;;                                  # the reference on the check rooms
  copy) switch="--set clone_opacity=copy" ;;                        # 3DGS's clones (the preset shares coverage)
  noterms) switch="--set w_normal=0 --set w_depth=0" ;;             # no prior term (the cue still read)
  el) switch="--set kernel=ellipsoid" ;;                            # 3DGS's kernel
  iface) switch="--set components=interface" ;;                     # GLINT's interface alone, no second set
  copyel) switch="--set clone_opacity=copy --set kernel=ellipsoid" ;; # both (declared after copy and el on 7301)
  photo) switch="--set w_l1=0.8 --set w_dssim=0.2"; tag=d64 ;;     # the ladder's follow-ups on the whole of GLINT
  nocons) switch="--set w_consistency=0"; tag=d64 ;;
  i_3dgs) switch=""; methods=3dgs; tag=d64 ;;                       # the ladder's last rung: the method, no list
  half) switch="--set w_depth=0.05 --set w_normal=0.15"; tag=d65 ;;     # the prior terms at half their weight
  quarter) switch="--set w_depth=0.025 --set w_normal=0.075"; tag=d65 ;; # and at a quarter (noterms: none)
  base) switch=""; tag=d66 ;;                                       # today's preset (its seed 0 is committed)
  agree_n) switch="--set prior_weight_ref=10"; tag=d66 ;;            # the normal prior x min(1, (10 / mean)^2)
  agree_dn) switch="--set prior_weight_ref=10 --set prior_weight_terms=depth,normal"; tag=d66 ;;  # both terms
  freesf) switch="--set w_normal=0 --set w_depth=0 --set w_consistency=0"; tag=d67 ;;  # no geometry term
  free) switch="--set w_normal=0 --set w_depth=0 --set w_consistency=0 --set kernel=ellipsoid"; tag=d67 ;;  # + ellipsoids
  cgrad) switch="--set consistency_grad=normal"; tag=d68 ;;          # the consistency moves only the normals
  cpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency"; tag=d68 ;;    # its pull on the depth
  cpull15) switch="--set prior_weight_ref=15 --set prior_weight_terms=consistency"; tag=d68 ;;  # x min(1, (ref / a)^2)
  gpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency --set prior_weight_where=off_glass"
         tag=d70 ;;                                                  # cpull, the glass keeping the whole pull
  dpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency --set prior_weight_where=off_glass \
--set prior_weight_from=0.5"; tag=d71 ;;                           # gpull from half the run (the glass found first)
  hpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency --set prior_weight_where=off_glass \
--set prior_weight_glass_t=0.5"; tag=d72 ;;                        # gpull, g = min(1, t / 0.5): half-found glass whole
  qpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency --set prior_weight_where=off_glass \
--set prior_weight_glass_t=0.25"; tag=d72 ;;                       # and from t 0.25
  epull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency --set prior_weight_where=off_glass \
--set prior_weight_from=0.1667"; tag=d72 ;;                        # gpull from 10/60 (the whole pull while t forms)
  i_el|i_copy|i_photo|i_cons) ;;
  *) echo "arm '$arm': use priors, 3dgs, copy, noterms, el, iface, copyel, i_el, i_copy, i_photo, i_cons, i_3dgs," \
          "photo, nocons, half, quarter, base, agree_n, agree_dn, freesf, free, cgrad, cpull, cpull15, gpull, dpull," \
          "hpull, qpull or epull" >&2
     exit 2 ;;
esac
case $arm in  # the ladder: each step keeps the ones before it
  i_el|i_copy|i_photo|i_cons) tag=d64; switch="--set components=interface --set kernel=ellipsoid" ;;&  # 3DGS's kernel
  i_copy|i_photo|i_cons) switch="$switch --set clone_opacity=copy" ;;&                       # 3DGS's clones
  i_photo|i_cons) switch="$switch --set w_l1=0.8 --set w_dssim=0.2" ;;&                      # 3DGS's L1 / D-SSIM
  i_cons) switch="$switch --set w_consistency=0" ;;                                          # no consistency term
esac
[ -n "${PRINT_SWITCH:-}" ] && { echo "$switch"; exit 0; }  # s69.sh's prior-sweep jobs read an arm's switch here
case $room in
  730[123]) data=${DATA73:-/work/data73} ;;
  980[123]) data=${DATA98:-/work/data98_r} ;;
  *) echo "room '$room': 7301-7303 or 9801-9803" >&2; exit 2 ;;
esac
WT=${WT:-/work/wt63}; RUNS=${RUNS:-/work/runs63}; PY=${PY:-/work/main/.venv/bin/python}
echo "=== $(date -u +%FT%TZ) ${tag}_$arm $room"
WT=$WT PY=$PY bash "$(dirname "$0")/run40.sh" $methods "$data/r$room" "$RUNS/${tag}_$arm" --set eval_every=1000 $switch \
    ${SEED:+--seed-ids $SEED}
echo "=== rc=$? $(date -u +%FT%TZ)"
