"""``prismstation new PROJECT (--scene scene.json | --product DIR | --images IMG IMG [IMG …])
[--points P.csv] [--measurements M.csv]`` (:func:`prismstation.ops.project.create`).

``--images``: two or more images with RPCs (any names; the RPCs from wherever
:func:`prismstation.io.rpc.read_rpc` finds them), one view per image named by its file's stem;
the scene file is written beside the project as ``<project>.scene.json``, the map zone the
UTM zone of the images' common footprint (images that do not overlap are refused). Tie points
are then matched as ``prismstation ties`` matches them (:mod:`prismstation.cli.ties`; exit
status 3 when none is found, the project saved without them) unless ``--no-ties``."""
from __future__ import annotations

from pathlib import Path

from prismstation.cli.ties import add_tie_options, match_and_save
from prismstation.errors import InputError
from prismstation.io.geoid import ConstantGeoid
from prismstation.io.project import SUFFIX, project_geoid
from prismstation.io.rpc_scene import scene_dict_for_images
from prismstation.model.points import HEIGHT_KINDS
from prismstation.ops.project import create


def register(sub) -> None:
    p = sub.add_parser("new", help="create a project from a scene, ground points and measurements")
    p.add_argument("project", help=f"project file to write ({SUFFIX})")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scene", help="scene.json (docs/formats.md)")
    src.add_argument("--product", help="a JAXA product folder (CEOS or GeoTIFF 1B2)")
    src.add_argument("--images", nargs="+", metavar="IMG",
                     help="two or more images with RPCs (GeoTIFF tags, .RPB, _RPC.TXT, DIMAP, .geom, NITF)")
    p.add_argument("--points", help="ground points CSV (id,E,N,H[,kind,height,...])")
    p.add_argument("--measurements", help="image measurements CSV (id,view,x,y)")
    p.add_argument("--crs", help="CRS of the ground points if not the scene's (e.g. EPSG:4326)")
    p.add_argument("--height", choices=HEIGHT_KINDS, help="height kind of points without a height column")
    p.add_argument("--geoid", help="geoid: a number (constant undulation, m), a grid file, or 'auto'")
    p.add_argument("--force", action="store_true", help="overwrite an existing project")
    p.add_argument("--no-ties", action="store_true",
                   help="--images: do not match tie points (prismstation ties does it later)")
    add_tie_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if Path(args.project).exists() and not args.force:  # before anything is read or written
        raise InputError("already exists (use --force to overwrite)", args.project)
    scene_path, scene_doc = args.scene, None
    if args.product:
        from prismstation.io.products import scene_dict_for_folder  # start-up: the CEOS reader, 0.1 s
        scene_path = Path(args.project).parent / "scene.json"
        scene_doc = scene_dict_for_folder(args.product, scene_path.parent)
    elif args.images:
        scene_path = Path(args.project).with_suffix(".scene.json")
        scene_doc = scene_dict_for_images(args.images, scene_path.parent)
    project = create(args.project, scene_path, args.points, args.measurements, crs=args.crs,
                     height=args.height, geoid=args.geoid, force=args.force, scene_doc=scene_doc)
    n_ms = len(project.measurements)
    kinds = [p.kind for p in project.points.values()]
    print(f"{args.project}: {kinds.count('GCP')} GCP, {kinds.count('ICP')} ICP, "
          f"{kinds.count('TIE')} tie points, {n_ms} measurements; geoid {_geoid_text(project)}")
    if args.images:
        print(f"{scene_path}: {len(project.scene.views)} {project.scene.sensor.description} "
              f"({', '.join(project.scene.views)}), CRS {project.scene.crs}")
        if not args.no_ties:
            return match_and_save(project, args.project, args.grid, command="new")
    return 0


def _geoid_text(project) -> str:
    """The geoid the project took, in words; an automatic one that found no grid says so."""
    geoid = project_geoid(project)
    if project.geoid.get("kind") != "auto":
        return geoid.describe()
    if isinstance(geoid, ConstantGeoid):
        return (f"{geoid.describe()} (auto: no EGM96/EGM2008 grid on PROJ's data paths — install "
                "proj-data or give --geoid)")
    return f"{geoid.describe()} (auto)"
