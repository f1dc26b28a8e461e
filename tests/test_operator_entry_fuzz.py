"""Operator entries, fuzzed (issue 15): 10^5 typed readings drawn from a grammar of what hands and keyboard
wedges type go through the one parser (:func:`bench.rigs.operators.parse_entry`) and the console operator; a
run of fuzzed prompts goes through the runner into a store. Every accepted reading is a finite number within the
prompt's bounds that keeps its text; every refusal is one line naming the prompt and what was expected; no NaN or
infinity is ever stored."""

from __future__ import annotations

import contextlib
import io
import math
import random
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from runner_support import StandInMover

from bench.errors import BenchError, ConfigError, PromptWithdrawn
from bench.protocols import Runner
from bench.protocols.base import Protocol
from bench.rigs.interfaces import Entry, Rig
from bench.rigs.operators import ConsoleOperator, parse_entry
from bench.steps import Prompt
from bench.store import Store

#: The fuzz's size: the issue's "10^5 fuzzed operator entries".
N_ENTRIES = 100_000

#: Prompts of every shape a protocol asks: a length near a commanded one (a confirmation far from it), an angle,
#: a mass with only a lower bound, a count without unit or bounds.
PROMPTS = (
    Prompt("Depth at P1", field="depth_mm", unit="mm", minimum=0.0, maximum=150.0, commanded={"cmd_depth_mm": 20.0}),
    Prompt("Tilt alpha", field="a_deg", unit="deg", minimum=-45.0, maximum=45.0),
    Prompt("Payload", field="load_kg", unit="kg", minimum=0.0),
    Prompt("Count", field="n_1"),
)

_DIGITS = "0123456789"
#: The pieces of the grammar: numbers as people and wedges type them, and what goes wrong around them.
_PIECES = (
    "+",
    "-",
    "\u2212",
    "--",
    "+-",
    " ",
    "  ",
    "\t",
    "\u00a0",
    "\u2009",
    "\n",
    ".",
    ",",
    ",,",
    "..",
    "\u066b",
    "e",
    "E",
    "e5",
    "e-3",
    "E+308",
    "e400",
    "e-400",
    "1e999",
    "-1e999",
    "0x1F",
    "1_000",
    "\u0661\u0662",
    "\uff11\uff12",
    "\u00b2",
    "\u00bd",
    "mm",
    "MM",
    "Mm",
    "in",
    "IN",
    '"',
    "''",
    "deg",
    "DEG",
    "\u00b0",
    "kg",
    "\u00b5m",
    "inch",
    "mm mm",
    "nan",
    "NaN",
    "-nan",
    "NAN",
    "inf",
    "-inf",
    "+inf",
    "Infinity",
    "-Infinity",
    "\u221e",
    "nan mm",
    "inf deg",
    "None",
    "null",
    "",
    "\x00",
    "\ufeff",
    "\U0001f600",
    "12,5",
    "0,4865 in",
    "-0,50 mm",
    "1.",
    ".5",
    ",5",
    "00012.3400",
    "1" * 15,
    "9" * 16,
    "1" * 400,
    "0." + "0" * 20 + "1",
    "9" * 14 + ".9",
    "150",
    "150.0000001",
    "-0",
    "45",
    "-45.0",
    "45.0000001",
    "20",
    "22.0001",
    "y",
    "yes",
)


def fuzzed_entries(seed: int, n: int) -> list[str]:
    """``n`` strings of 1 to 6 pieces of the grammar and runs of random digits (seeded, so a failure replays)."""
    rng = random.Random(seed)
    entries = []
    for _ in range(n):
        parts = []
        for _ in range(rng.randint(1, 6)):
            if rng.random() < 0.4:
                parts.append("".join(rng.choices(_DIGITS, k=rng.choice((1, 2, 3, 5, 8, 15, 16, 40)))))
            else:
                parts.append(rng.choice(_PIECES))
        entries.append("".join(parts))
    return entries


def _check_accepted(prompt: Prompt, value: object, typed: str) -> None:
    assert isinstance(value, Entry) and type(float(value)) is float, (prompt.text, typed, value)
    assert math.isfinite(value), (prompt.text, typed, value)
    low = -math.inf if prompt.minimum is None else prompt.minimum
    high = math.inf if prompt.maximum is None else prompt.maximum
    assert low <= value <= high, (prompt.text, typed, value)
    assert value.typed == typed.strip(), (typed, value.typed)
    assert not any(c.isdigit() and not c.isascii() for c in typed), typed  # no other script's digits


def _check_refusal(prompt: Prompt, exc: BenchError, typed: str) -> None:
    message = str(exc)
    assert "\n" not in message and "\r" not in message, (typed, message)
    assert message.startswith(f"{prompt.text}: ") and "expected" in message, (typed, message)


def test_1e5_fuzzed_entries_through_the_parser_are_finite_in_bounds_or_one_line():
    started = time.perf_counter()
    entries = fuzzed_entries(15, N_ENTRIES)
    accepted = refused = confirmations = 0
    for n, text in enumerate(entries):
        prompt = PROMPTS[n % len(PROMPTS)]
        try:
            value, question = parse_entry(prompt, text)
        except ConfigError as exc:
            _check_refusal(prompt, exc, text)
            refused += 1
        else:
            _check_accepted(prompt, value, text)
            accepted += 1
            if question:
                assert "\n" not in question.strip() and question.endswith("keep it? [y/N] "), question
                confirmations += 1
    elapsed_s = time.perf_counter() - started
    assert accepted + refused == N_ENTRIES
    # the grammar reaches both sides of every rule (the figures move only when the grammar or the seed does)
    assert accepted > 5_000 and refused > 50_000 and confirmations > 100, (accepted, refused, confirmations)
    print(
        f"{N_ENTRIES} entries: {accepted} accepted ({confirmations} to confirm), {refused} refused, {elapsed_s:.2f} s"
    )


def test_1e5_fuzzed_entries_at_the_console_give_finite_readings_and_one_line_per_refusal():
    entries = iter(fuzzed_entries(1515, N_ENTRIES))

    def read_line(_prompt: str) -> str:
        try:
            return next(entries)
        except StopIteration:
            raise EOFError from None

    operator, answers, stderr = ConsoleOperator(read_line), [], io.StringIO()
    with contextlib.redirect_stderr(stderr):
        for n in range(N_ENTRIES):
            prompt = PROMPTS[n % len(PROMPTS)]
            try:
                answers.append((prompt, operator.ask(prompt)))
            except PromptWithdrawn:  # the fuzz ran out: end of input withdraws the prompt, once
                break
    for prompt, value in answers:
        _check_accepted(prompt, value, value.typed)
    # the prompts are printed without a newline (the answer is typed on the same line); every newline ends a
    # refusal, and every refusal is one line ending in "try again"
    lines = stderr.getvalue().split("\n")[:-1]
    assert len(lines) > 50_000 and len(answers) > 500, (len(lines), len(answers))
    for line in lines:
        assert line.endswith("; try again") and line.count("try again") == 1, line
        assert "Traceback" not in line


@pytest.mark.parametrize(
    ("prompt", "text", "message"),
    [
        (PROMPTS[3], "3 in", "Count: '3 in' is not a reading; expected a number without unit"),  # was 76.2
        (PROMPTS[3], "3 mm", "Count: '3 mm' is not a reading; expected a number without unit"),
        (
            PROMPTS[1],
            "1 in",
            "Tilt alpha: '1 in' is not a reading in deg; expected a number, optionally followed by deg",
        ),
        (PROMPTS[2], "nan kg", "Payload: 'nan' is not a reading in kg; expected a number, optionally followed by kg"),
        (PROMPTS[2], "45\u0661\u0662", "Payload: reading '45\u0661\u0662' is not a length"),  # was 4512
        (PROMPTS[0], "\uff11\uff12", "Depth at P1: reading '\uff11\uff12' is not a length"),  # full-width 12
        (PROMPTS[0], "1" * 400, f"Depth at P1: reading '{'1' * 400}' has 400 digits, expected at most 15"),
        (PROMPTS[0], "1e999", "Depth at P1: reading '1e999' is not a length"),
    ],
)
def test_entries_the_fuzz_found_or_the_issue_named_are_refused_in_one_line(prompt, text, message):
    with pytest.raises(ConfigError) as refused:
        parse_entry(prompt, text)
    assert str(refused.value).startswith(message) and "\n" not in str(refused.value)


def test_a_count_takes_a_bare_number_and_an_angle_its_own_unit():
    assert parse_entry(PROMPTS[3], " 7 ") == (Entry(7.0, "7"), "")
    assert parse_entry(PROMPTS[1], "-1,5 deg") == (Entry(-1.5, "-1,5 deg"), "")
    assert parse_entry(PROMPTS[0], "0,4865 in")[0] == pytest.approx(12.3571)


class _FuzzedPrompts(Protocol):
    """Fuzzed prompts only: one reading each, stored at once (no move, no capture)."""

    name, version = "test_fuzzed_prompts", "1"

    def steps(self):
        for n in range(200):
            prompt = PROMPTS[n % len(PROMPTS)]
            yield Prompt(
                prompt.text,
                field=prompt.field,
                unit=prompt.unit,
                minimum=prompt.minimum,
                maximum=prompt.maximum,
                commanded=prompt.commanded,
                kind="fuzz_reading",
                cycle=n + 1,
            )


class _StillRobot(StandInMover):
    """A robot that is never asked to move (the protocol only prompts)."""

    def move_to(self, target, *, velocity_pct):
        raise AssertionError(f"no move expected, got {target}")

    def stop(self):
        pass

    def shutdown(self):
        pass

    def settings(self):
        return {"kind": "still"}


class _NoInstrument:
    def measure(self, capture):
        raise AssertionError(f"no capture expected, got {capture}")

    def settings(self):
        return {}


def test_fuzzed_prompts_of_a_run_store_no_nan_or_inf_and_keep_the_text_as_typed():
    entries = iter(fuzzed_entries(151515, 40_000))
    operator = ConsoleOperator(lambda _prompt: next(entries))
    rig = Rig(_StillRobot(), _NoInstrument(), operator, speed_factor=1e6, sleep=lambda s: None)
    with Store(":memory:") as store, contextlib.redirect_stderr(io.StringIO()):
        result = Runner(rig, store).run(_FuzzedPrompts())
        samples = store.samples(result.run_id)
    assert (result.exit_status, result.samples) == ("completed", 200), result.reason
    for n, sample in enumerate(samples):
        prompt = PROMPTS[n % len(PROMPTS)]
        value = sample.values[prompt.field]
        assert math.isfinite(value) and sample.raw["entered"] == value, sample
        assert isinstance(sample.raw["typed"], str) and sample.raw["typed"] == sample.raw["typed"].strip()
        _check_accepted(prompt, parse_entry(prompt, sample.raw["typed"])[0], sample.raw["typed"])
        assert parse_entry(prompt, sample.raw["typed"])[0] == value  # the stored text reads back as the value


@given(st.lists(st.sampled_from(_PIECES) | st.text(max_size=3), max_size=8).map("".join) | st.text(max_size=60))
@settings(max_examples=400, deadline=None)
def test_any_text_for_any_prompt_is_a_finite_reading_or_one_line(text):
    for prompt in PROMPTS:
        try:
            value, _ = parse_entry(prompt, text)
        except ConfigError as exc:
            _check_refusal(prompt, exc, text)
        else:
            _check_accepted(prompt, value, text)
