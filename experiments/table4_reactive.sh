#!/usr/bin/env bash
# Table IV's planners (Ours, mpc_goal, DWA, TEB) on stages 5-7 under reactive ORCA and social-force
# crowds (issue 37), both collision rules, laid out so that `mjnav tables` reads them:
#
#   <out>/<crowd>/<slug>/<stage>_contact.jsonl, <stage>_scan.jsonl   finished evaluations
#   <out>/<crowd>/<slug>/<stage>.jsonl                                 the one running now (resumable)
#   <out>/<crowd>/<slug>/contact/<stage>.jsonl                         contact run the paper's rule settles from
#   <out>/logs/<crowd>_<slug>_<stage>_<rule>.log, <out>/logs/driver.log
#
# slugs as in `mjnav tables table=4 planners=mpc_goal,dwa,mpc_tracked`: ours, planner_mpc_goal, planner_dwa, teb,
# planner_mpc_tracked (issue 39: planning around the LiDAR tracks; run it with METHODS=mpc_tracked), ours_tracks
# ("Ours + tracks": Ours through the tracks' crowd shield, stageK_tracks_policy; METHODS=ours_tracks).
# Also mpc_crowd (privileged), dwa+tracks and teb+tracks (planner.tracks=true; slugs planner_mpc_crowd,
# planner_dwa_tracks, planner_teb_tracks): METHODS="mpc_crowd dwa+tracks teb+tracks".
# Order: cheapest first, both crowds per phase: (Ours, mpc_goal), then DWA, then TEB; per stage the
# contact rule first, whose settled episodes the paper's rule (task.collision=scan) reuses.
# One evaluation at a time, in this process's Python (mjnav from PYTHONPATH: run it from a pinned
# checkout; resuming needs the same commit). Finished steps are skipped, so a rerun resumes.
#
# usage: PYTHONPATH=<checkout> experiments/table4_reactive.sh [OUT] [EPISODES] [WORKERS]
# tables: experiments/table4_reactive.sh tables [OUT] [EPISODES]
# Environment: CROWDS (default "orca social_force"), STAGES ("stage5 stage6 stage7"), METHODS
# ("ours mpc_goal dwa teb": which to run), REACTIVE (true; false = the non-reactive control of the
# social metrics, same crowds and episodes, under <out>/<crowd>_nonreactive/), PYTHON (python).
set -u
PY=${PYTHON:-python}
CROWDS=${CROWDS:-"orca social_force"}
STAGES=${STAGES:-"stage5 stage6 stage7"}
METHODS=${METHODS:-"ours mpc_goal dwa teb"}
REACTIVE=${REACTIVE:-true}
SUFFIX=""
[ "$REACTIVE" = true ] || SUFFIX="_nonreactive"

wanted() { case " $METHODS " in *" $1 "*) return 0;; *) return 1;; esac; }

tables() {  # the tables from what is there (unfinished runs as "n of N"), one per crowd model
    local out=$1 episodes=$2 crowd
    for crowd in $CROWDS; do
        echo "### crowd.model=$crowd, crowd.reactive=$REACTIVE"
        echo
        "$PY" -m mjnav tables table=4 out="$out/$crowd$SUFFIX" episodes="$episodes" run=false planners=mpc_goal,dwa,mpc_tracked,mpc_crowd,dwa+tracks,teb+tracks \
            social=true
        echo
    done
}

one() {  # one evaluation: crowd, slug, policy, stage, rule, then extra `mjnav evaluate` arguments
    local crowd=$1 slug=$2 policy=$3 stage=$4 rule=$5
    shift 5
    local dir="$OUT/$crowd$SUFFIX/$slug" log="$OUT/logs/${crowd}${SUFFIX}_${slug}_${stage}_${rule}.log"
    if [ -f "$dir/${stage}_${rule}.jsonl" ]; then return 0; fi
    mkdir -p "$dir/contact" "$OUT/logs"
    local extra=()
    if [ "$rule" = scan ]; then extra=(from_contact="$dir/contact"); fi
    echo "$(date -u +%FT%TZ) start $crowd$SUFFIX $slug $stage $rule" >> "$OUT/logs/driver.log"
    "$PY" -m mjnav evaluate task="$stage" policy="$policy" episodes="$EPISODES" workers="$WORKERS" out="$dir" \
        task.collision="$rule" task.crowd.model="$crowd" task.crowd.reactive="$REACTIVE" "${extra[@]}" "$@" >> "$log" 2>&1
    local rc=$?
    echo "$(date -u +%FT%TZ) end $crowd$SUFFIX $slug $stage $rule rc=$rc" >> "$OUT/logs/driver.log"
    [ $rc -eq 0 ] || return $rc
    if [ "$rule" = contact ]; then cp "$dir/$stage.jsonl" "$dir/${stage}_contact.jsonl" && mv "$dir/$stage.jsonl" "$dir/contact/$stage.jsonl"
    else mv "$dir/$stage.jsonl" "$dir/${stage}_scan.jsonl"; fi
}

pair() {  # both rules of one method and stage, the contact rule first: crowd, slug, policy, stage, extra arguments
    local crowd=$1 slug=$2 policy=$3 stage=$4
    shift 4
    one "$crowd" "$slug" "$policy" "$stage" contact "$@" && one "$crowd" "$slug" "$policy" "$stage" scan "$@"
}

if [ "${1:-}" = tables ]; then
    tables "${2:-evals/table4_reactive}" "${3:-1000}"
    exit 0
fi
OUT=${1:-evals/table4_reactive}
EPISODES=${2:-1000}
WORKERS=${3:-1}
for crowd in $CROWDS; do
    for stage in $STAGES; do
        wanted ours && pair "$crowd" ours "${stage}_policy" "$stage"
        wanted ours_tracks && pair "$crowd" ours_tracks "${stage}_tracks_policy" "$stage"
        wanted mpc_goal && pair "$crowd" planner_mpc_goal mpc_goal "$stage"
    done
done
for method in dwa teb mpc_tracked mpc_crowd dwa+tracks teb+tracks; do
    wanted "$method" || continue
    planner=${method%+tracks}
    slug=planner_$planner
    args=()
    [ "$method" = teb ] && slug=teb
    if [ "$method" != "$planner" ]; then slug=planner_${planner}_tracks; args=(planner.tracks=true); fi
    for crowd in $CROWDS; do
        for stage in $STAGES; do pair "$crowd" "$slug" "$planner" "$stage" "${args[@]}"; done
    done
done
echo "$(date -u +%FT%TZ) all done" >> "$OUT/logs/driver.log"
