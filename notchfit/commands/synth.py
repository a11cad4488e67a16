"""``notchfit synth``: generate a synthetic study with a known hidden effect."""

from __future__ import annotations

from pathlib import Path

from ..studies.synth import generate_study, list_recipes, load_recipe
from ._common import InputError, count_option, jobs_option

NAME = "synth"
ORDER = 10
HELP = "generate a synthetic study from a recipe (ground truth in truth.json)"
DESCRIPTION = """Generate a synthetic study: several paper-like bend/unbend tests simulated by the
friction model (reference solver) with base parameters drawn away from the paper's values,
optionally one hidden physical effect (a cause id of docs/data-formats.md), seeded measurement
noise and a random plane transform per experiment. Writes OUT/<experiment>/ per docs/data-formats.md
and OUT/truth.json (the ground truth; no analysis command reads it).

RECIPE is a TOML file or the name of a shipped recipe in datasets/recipes/:
  paper8              the paper's eight tests, no hidden effect
  null                six tests, no hidden effect
  proximal_friction, static_friction, joint_hysteresis, external_load,
  stiffness_gradient, calibration_error   six tests with that effect

Examples:
  notchfit synth paper8 --out study/
  notchfit synth proximal_friction --out pf/ --seed 3
  notchfit synth my_recipe.toml --out s/ --images --jobs 2
  notchfit synth --list
"""


def add_arguments(parser) -> None:
    parser.add_argument("recipe", nargs="?", help="recipe TOML file or shipped recipe name")
    parser.add_argument("--out", type=Path, help="study folder to create")
    parser.add_argument("--seed", type=count_option(0), default=None, help="override the recipe's seed")
    parser.add_argument("--images", action="store_true", default=None,
                        help="also render one image per sample (needs notchfit.vision.render)")
    parser.add_argument("--experiments", type=count_option(1), default=None,
                        help="keep only the first N experiments of the recipe")
    parser.add_argument("--samples", type=count_option(1), nargs=2, metavar=("N_UP", "N_DOWN"), default=None,
                        help="samples on the loading and the unloading ramp")
    parser.add_argument("--jobs", type=jobs_option, default=1, help="worker processes (default 1)")
    parser.add_argument("--force", action="store_true", help="replace an existing study in OUT")
    parser.add_argument("--list", action="store_true", help="list the shipped recipes and exit")


def run(args) -> int:
    if args.list:
        for name in list_recipes():
            r = load_recipe(name)
            print(f"{name:20s} {r.cause:20s} {len(r.experiments)} experiments  {r.description}")
        return 0
    if not args.recipe or args.out is None:
        raise InputError("need RECIPE and --out DIR (or --list)")
    recipe = load_recipe(args.recipe)
    if args.experiments is not None or args.samples is not None:
        n_up, n_down = args.samples if args.samples else (None, None)
        recipe = recipe.scaled(n_experiments=args.experiments, n_up=n_up, n_down=n_down)
    study = generate_study(recipe, args.out, seed=args.seed, force=args.force, jobs=args.jobs,
                           images=args.images)
    n = sum(len(e.samples) for e in study.experiments)
    print(f"wrote {len(study.experiments)} experiments ({n} samples) to {args.out} "
          f"(recipe {recipe.name}, seed {study.seed}); ground truth in {Path(args.out) / 'truth.json'}")
    return 0
