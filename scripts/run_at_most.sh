# Sourced by the check scripts: runs a shell function over items in the background, a bounded
# number at a time.
#
#   run_at_most LIMIT FUNCTION ITEM...
#
# Calls `FUNCTION ITEM` for every item, at most LIMIT of them at once, and returns when all have
# ended. Their exit codes are not collected: each call records its own outcome (the scripts write
# a status file beside each log).
run_at_most() {
    local limit="$1" fn="$2"
    shift 2
    local running=0 item
    for item in "$@"; do
        if [ "$running" -ge "$limit" ]; then
            wait -n || true
            running=$((running - 1))
        fi
        "$fn" "$item" &
        running=$((running + 1))
    done
    wait || true
}
