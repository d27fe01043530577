"""The points of a study: grids, ranges and Monte Carlo samples over scenario keys.

    --grid controller.L_hat_ratio=0.5,1.0,1.5      listed values
    --grid controller.L_hat_ratio=0.5:1.5:0.25     START:STOP:STEP, STOP included when on the step
    --sample plant.R_ohm=uniform(0.4,0.6)          drawn --samples N times, numpy's PCG64 seeded by --seed
    --sample controller.R_hat_ratio=normal(1,0.1)
    --grid scenario.seed=1:100:1                   the ADC-noise seed is a key like any other

The study is the product of the grids; with samples, each grid point is run with each of the same N draws
(common random numbers: grid points are compared on equal draws, not on different luck).
A point is named by its overrides (`point_id`, "key=value;key=value"): the same command gives the same
points in the same order, which is what `--resume` and a serial-vs-cluster comparison rely on.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation

import numpy as np

MAX_POINTS = 10_000_000
_SAMPLE = re.compile(r"^\s*(uniform|normal)\s*\(\s*([^,()]+)\s*,\s*([^,()]+)\s*\)\s*$")


class SpaceError(ValueError):
    """A --grid / --sample / --bisect argument that cannot be used, with what is allowed."""


@dataclass(frozen=True)
class Sample:
    key: str
    dist: str  # uniform | normal
    a: float  # uniform: low; normal: mean
    b: float  # uniform: high; normal: standard deviation

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.dist == "uniform":
            return rng.uniform(self.a, self.b, n)
        return rng.normal(self.a, self.b, n)


@dataclass
class Space:
    grid: list[tuple[str, list[str]]] = field(default_factory=list)
    samples: list[Sample] = field(default_factory=list)
    n_samples: int = 0
    seed: int = 0

    @property
    def keys(self) -> list[str]:
        return [k for k, _ in self.grid] + [s.key for s in self.samples]

    def size(self) -> int:
        n = math.prod(len(v) for _, v in self.grid)
        return n * (self.n_samples if self.samples else 1)

    def points(self) -> list[dict[str, str]]:
        """Every point, in the study's order: the grid (last key fastest), then the samples."""
        combos = list(itertools.product(*[[(k, v) for v in vals] for k, vals in self.grid]))
        if not self.samples:
            return [dict(c) for c in combos]
        rng = np.random.default_rng(self.seed)
        draws = {s.key: s.draw(rng, self.n_samples) for s in self.samples}
        return [
            {**dict(c), **{k: repr(float(d[i])) for k, d in draws.items()}}
            for c in combos
            for i in range(self.n_samples)
        ]

    def distinct_values(self) -> dict[str, list[str]]:
        """Per key, the values to validate before anything runs (a sample: its drawn extremes)."""
        out = {k: list(v) for k, v in self.grid}
        if self.samples:
            rng = np.random.default_rng(self.seed)
            for s in self.samples:
                d = s.draw(rng, self.n_samples)
                out[s.key] = [repr(float(d.min())), repr(float(d.max()))]
        return out

    def spec(self) -> dict[str, object]:
        return {
            "grid": [[k, v] for k, v in self.grid],
            "samples": [[s.key, s.dist, s.a, s.b] for s in self.samples],
            "n_samples": self.n_samples,
            "seed": self.seed,
        }


def point_id(values: dict[str, str]) -> str:
    return ";".join(f"{k}={v}" for k, v in values.items())


def _key_value(item: str, flag: str, example: str) -> tuple[str, str]:
    key, sep, value = item.partition("=")
    if not sep or not key.strip() or not value.strip():
        raise SpaceError(f"{flag} {item!r}: expected KEY=..., e.g. {flag} {example}")
    return key.strip(), value.strip()


def _dec(text: str, what: str) -> Decimal:
    try:
        d = Decimal(text.strip())
    except InvalidOperation:
        raise SpaceError(f"{what}: {text!r} is not a number") from None
    if not d.is_finite():
        raise SpaceError(f"{what}: {text!r} is not a finite number")
    return d


def expand_range(key: str, text: str) -> list[str]:
    """START:STOP:STEP in decimal arithmetic (0.1 steps give 0.3, not 0.30000000000000004); STOP included
    when it falls on a step."""
    parts = text.split(":")
    if len(parts) != 3:
        raise SpaceError(f"--grid {key}={text}: a range is START:STOP:STEP, e.g. {key}=0.5:1.5:0.25")
    start, stop, step = (_dec(p, f"--grid {key}={text}") for p in parts)
    if step <= 0:
        raise SpaceError(f"--grid {key}={text}: STEP must be > 0")
    if stop < start:
        raise SpaceError(f"--grid {key}={text}: STOP must be >= START")
    n = int((stop - start) / step) + 1
    if n > MAX_POINTS:
        raise SpaceError(f"--grid {key}={text}: {n} values; at most {MAX_POINTS}")
    vals = [start + i * step for i in range(n)]
    integral = all(p == p.to_integral_value() for p in (start, step))
    return [str(int(v)) if integral else _plain(v) for v in vals]


def _plain(d: Decimal) -> str:
    s = format(d.normalize(), "f")
    return s if s not in ("-0", "") else "0"


def parse_grid(items: list[str]) -> list[tuple[str, list[str]]]:
    grid: list[tuple[str, list[str]]] = []
    for item in items:
        key, text = _key_value(item, "--grid", "controller.L_hat_ratio=0.5,1.0 or =0.5:1.5:0.25")
        if ":" in text and "," not in text:
            vals = expand_range(key, text)
        else:
            vals = [v.strip() for v in text.split(",") if v.strip()]
        if not vals:
            raise SpaceError(f"--grid {item!r}: no values")
        if len(set(vals)) != len(vals):
            raise SpaceError(f"--grid {item!r}: a value is listed twice")
        grid.append((key, vals))
    return grid


def parse_sample(item: str) -> Sample:
    key, text = _key_value(item, "--sample", "controller.R_hat_ratio=normal(1,0.1)")
    m = _SAMPLE.match(text)
    if not m:
        raise SpaceError(f"--sample {item!r}: expected uniform(LOW,HIGH) or normal(MEAN,STD)")
    dist = m.group(1)
    a, b = (float(_dec(m.group(i), f"--sample {item}")) for i in (2, 3))
    if dist == "uniform" and not a < b:
        raise SpaceError(f"--sample {item!r}: uniform(LOW,HIGH) needs LOW < HIGH")
    if dist == "normal" and not b > 0:
        raise SpaceError(f"--sample {item!r}: normal(MEAN,STD) needs STD > 0")
    return Sample(key, dist, a, b)


def build(grid: list[str], samples: list[str], n_samples: int | None, seed: int) -> Space:
    space = Space(parse_grid(grid), [parse_sample(s) for s in samples], n_samples or 0, seed)
    keys = space.keys
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise SpaceError(f"{', '.join(dup)}: a key is given twice (--grid/--sample/--bisect)")
    if space.samples and not n_samples:
        raise SpaceError("--sample needs --samples N (how many draws), e.g. --samples 200")
    if n_samples is not None and not space.samples:
        raise SpaceError("--samples is for --sample KEY=DIST: there is nothing to draw")
    if n_samples is not None and not 1 <= n_samples <= MAX_POINTS:
        raise SpaceError(f"--samples {n_samples}: allowed 1 .. {MAX_POINTS}")
    if not 0 <= seed <= 0xFFFFFFFF:
        raise SpaceError(f"--seed {seed}: allowed 0 .. 4294967295")
    if space.size() > MAX_POINTS:
        raise SpaceError(f"the study has {space.size()} points; at most {MAX_POINTS}")
    return space
