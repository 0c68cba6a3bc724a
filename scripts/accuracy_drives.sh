# The 28 drives of docs/accuracy.md ("Consensus against naive over 28 drives"), as
# scene-seed-movers: street, campus and loop with seeds 1, 2, 5, 6, 8, 9, 10 and 11 and 4 movers,
# seed 7 with 8 movers (street: seeds 3 and 12 with 8), and how their captures are made (by
# sim_once of replay_eval.sh). Sourced by accuracy_seeds.sh and accuracy_draws.sh.
# shellcheck shell=bash disable=SC2034,SC2154 # drives is read, cndt set, by the scripts that source this
drives=()
for scene in street campus loop; do
  for seed in 1 2 5 6 8 9 10 11; do drives+=("$scene-$seed-4"); done
  drives+=("$scene-7-8")
done
drives=("${drives[@]/street-7-8/street-3-8}")
drives+=(street-12-8)

# shellcheck source=scripts/replay_eval.sh
source "$(dirname "${BASH_SOURCE[0]}")/replay_eval.sh"

# drive_capture DRIVE SECONDS DIR: simulates DRIVE (scene-seed-movers) for SECONDS with $cndt
# into DIR/DRIVE unless its capture is there. Under a lock: parallel jobs may want one capture.
drive_capture() {
  local scene seed movers dir=$3/$1
  IFS=- read -r scene seed movers <<<"$1"
  (
    flock 9
    sim_once "$dir" --scene "$scene" --duration "$2" --movers "$movers" --seed "$seed"
  ) 9>"$3/.lock-$1"
}
