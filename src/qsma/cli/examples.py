"""``qsma examples``: the example configurations shipped with qsma, listed or copied."""
from __future__ import annotations

HELP = "list the example configuration and mesh files shipped with qsma, or copy them"


def add_arguments(p):
    p.add_argument("--copy", metavar="DIR",
                   help="copy the example files into DIR (then: qsma run "
                        "DIR/sandwich-2d.toml --out OUT)")


def execute(args) -> int:
    from ..examples.files import copy_examples, example_dir, example_files
    if args.copy is not None:
        for path in copy_examples(args.copy):
            print(path)
        return 0
    print(f"example files in {example_dir()}:")
    for name in example_files():
        print(f"  {name}")
    print("run one with: qsma run PATH --out OUT; copy them to edit: qsma examples "
          "--copy DIR; built-in models: qsma run --example NAME")
    return 0
