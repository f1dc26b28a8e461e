"""Mutation check of the pkm5 safety chain (issue 31): put each fault back into a temporary copy of the firmware or
driver source and show that the test written for it fails there (and passes on the source as it is).

    python tools/safety_mutations.py            # every mutation; exit 1 if a test misses its fault
    python tools/safety_mutations.py item7      # one

Each mutation is a text replacement in one file; the copy is made with ``git ls-files`` plus the working tree, so
uncommitted edits are checked as well. Slow (the firmware tests run on the emulated MCU): about a minute each.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FW = "firmware/pkm5/pkm5.c"
DRIVER = "bench/robots/pkm5.py"
SIMULATOR = "bench/simulators/pkm5.py"
SAFETY = "tests/test_firmware_pkm5_safety.py::"
DRIVER_TESTS = "tests/test_robots_pkm5_driver.py::"

#: name -> (file, text as it is, the fault put back, the test that must catch it)
MUTATIONS = {
    "item6-stop-clears-trip": (
        FW,
        "  if (watchdog_tripped) {\n    watchdog_tripped = 0;",
        "  if (watchdog_tripped && !stopped) {\n    watchdog_tripped = 0;",
        SAFETY + "test_a_stop_during_the_ramp_down_keeps_the_trip_and_the_next_move_is_watched",
    ),
    "item7-any-line-feeds-watchdog": (
        FW,
        "  if (length == 0) return;\n  uint8_t body;",
        ("  if (length == 0) return;\n  cli(); last_beat_tick = ticks; sei();\n  uint8_t body;"),
        SAFETY + "test_babble_of_short_invalid_lines_does_not_feed_the_watchdog",
    ),
    "item8-any-verb-is-heartbeat": (
        FW,
        "if (strcmp(verb, HOST_VERBS[i]) == 0) {",
        "if (1) {",
        SAFETY + "test_replies_echoed_back_are_no_heartbeat",
    ),
    "item9-xor-line-on-crc-link": (
        FW,
        "if (!frame_ok(line, length, protocol, &body)) {",
        "if (!frame_ok(line, length, protocol, &body) && !frame_ok(line, length, 1, &body)) {",
        SAFETY + "test_a_crc_line_that_lost_two_characters_does_not_downgrade_the_link",
    ),
    "item9-protocol-1-downgrades": (
        FW,
        " || args[0] < protocol)",
        ")",
        SAFETY + "test_a_crc_line_that_lost_two_characters_does_not_downgrade_the_link",
    ),
    "watchdog-off": (
        FW,
        "else if (WATCHDOG_TICKS > 0 && state != HALT",
        "else if (0 && state != HALT",
        SAFETY + "test_a_silent_host_mid_move_loses_the_drives_within_250_ms",
    ),
    "item10-no-heartbeat-awaiting-ok": (
        DRIVER,
        '("OK", "DONE"), self.reply_timeout_s, heartbeat=True)',
        '("OK", "DONE"), self.reply_timeout_s)',
        DRIVER_TESTS + "test_the_heartbeat_flows_while_a_lost_move_acceptance_is_awaited",
    ),
    "item11-stop-sent-once": (
        DRIVER,
        "STOP_SENDS = 10",
        "STOP_SENDS = 1",
        DRIVER_TESTS + "test_a_stop_from_another_thread_is_resent_until_acknowledged",
    ),
    "item12-firmware-executes-a-resent-move": (
        FW,
        "if (protocol >= 3 && tag == last_move_tag) replay_move();",
        "if (0) replay_move();",
        SAFETY + "test_a_move_resent_with_its_tag_is_answered_not_executed_again",
    ),
    "item12-simulator-executes-a-resent-move": (
        SIMULATOR,
        ('if verb == "MOVE" and self.protocol >= 3 and tag == self._last_move[0]:'),
        "if False:",
        "tests/test_pkm5_noisy_link.py",
    ),
    "item12-move-resent-across-a-stop": (
        DRIVER,
        "if self._stops_requested != stops_before:",
        "if False:",
        DRIVER_TESTS + "test_an_unacknowledged_move_is_not_resent_after_a_stop",
    ),
}


def copy_tree(dest: Path) -> None:
    files = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    for name in files:
        source = ROOT / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def run_test(tree: Path, test: str) -> bool:
    done = subprocess.run(
        [sys.executable, "-m", "pytest", test, "-q", "-x", "-p", "no:cacheprovider"],
        cwd=tree,
        env={"PYTHONPATH": str(tree), "PATH": subprocess.os.environ["PATH"]},
        capture_output=True,
        text=True,
        check=False,
    )
    return done.returncode == 0


def main(names: list[str]) -> int:
    missed = 0
    for name in names or list(MUTATIONS):
        path, original, fault, test = MUTATIONS[name]
        with tempfile.TemporaryDirectory() as tmp:
            tree = Path(tmp)
            copy_tree(tree)
            text = (tree / path).read_text()
            if text.count(original) != 1:
                print(f"{name}: the text to mutate is not in {path} exactly once: update the mutation")
                missed += 1
                continue
            (tree / path).write_text(text.replace(original, fault))
            caught = not run_test(tree, test)
        print(f"{name}: {'caught' if caught else 'MISSED'} by {test.split('::')[-1]}", flush=True)
        missed += not caught
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
