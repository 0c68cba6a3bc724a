# The 28 drives of docs/accuracy.md ("Consensus against naive over 28 drives"), as
# scene-seed-movers: street, campus and loop with seeds 1, 2, 5, 6, 8, 9, 10 and 11 and 4 movers,
# seed 7 with 8 movers (street: seeds 3 and 12 with 8). Sourced by accuracy_seeds.sh and
# accuracy_draws.sh.
# shellcheck shell=bash disable=SC2034 # drives is read by the scripts that source this
drives=()
for scene in street campus loop; do
  for seed in 1 2 5 6 8 9 10 11; do drives+=("$scene-$seed-4"); done
  drives+=("$scene-7-8")
done
drives=("${drives[@]/street-7-8/street-3-8}")
drives+=(street-12-8)
