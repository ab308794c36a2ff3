"""The cross-dataset protocol with training-only sources (issue 34: more people and sensors).

``simenv eval classifier --protocol cross-dataset`` reads the room corpora and MSRC-12;
this script adds the sources that train every network but are never left out
(``--kindergator``: Kinder-Gator, :func:`simenv.learning.cross_dataset.kinder_gator_clips`)
and can skip the leave-subjects-out networks (``--cross-only``: half the CPU, for comparing
training sources). It writes ``OUT/cross_dataset.json`` (as the command does, with
``command`` naming this script) and ``OUT/confusion_<dataset>.json/.png``, and prints the
summary table. One network at a time, one thread each (``--jobs`` trains several at once).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import torch

from simenv.core.config import shared_data_root
from simenv.learning.cross_dataset import (
    KINDER_GATOR,
    load_corpus,
    run_cross_dataset,
    summary_table,
)
from simenv.learning.recognition import RecognitionConfig
from simenv.learning.recognition_report import write_confusions


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--msrc12", help="MSRC-12 folder (p06 never read)")
    parser.add_argument("--kindergator", help="Kinder-Gator folder (trains, never left out)")
    parser.add_argument("--config", help="RecognitionConfig TOML/JSON of every network")
    parser.add_argument("--cross-only", action="store_true",
                        help="no leave-subjects-out networks (within-dataset 'not run')")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/cross-dataset-sources"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    config = RecognitionConfig.from_file(args.config) if args.config else RecognitionConfig()
    clips = load_corpus(shared_data_root(None) / "gestures", msrc12_folder=args.msrc12,
                        kinder_gator_folder=args.kindergator)
    start = time.time()
    result = run_cross_dataset(clips, config, jobs=args.jobs, progress=False,
                               cross_only=args.cross_only,
                               train_only=(KINDER_GATOR,) if args.kindergator else ())
    result["wall_s"] = round(time.time() - start, 1)
    result["command"] = ("python benchmarks/cross_dataset_sources.py "
                         + shlex.join(sys.argv[1:]))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "cross_dataset.json").write_text(json.dumps(result, indent=1))
    for name, d in result["datasets"].items():
        write_confusions({cond: c["cross_dataset"] for cond, c in d["conditions"].items()},
                         result["labels"], args.out, f"confusion_{name}")
    print(summary_table(result))
    print(f"outputs in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
