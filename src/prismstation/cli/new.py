"""``prismstation new PROJECT --scene scene.json [--points P.csv] [--measurements M.csv]``."""
from __future__ import annotations

from pathlib import Path

from prismstation.errors import InputError
from prismstation.io.points import read_ground_points, read_measurements
from prismstation.io.project import SUFFIX, save_project
from prismstation.io.scene import read_scene
from prismstation.model.points import HEIGHT_KINDS
from prismstation.model.project import Project


def register(sub) -> None:
    p = sub.add_parser("new", help="create a project from a scene, ground points and measurements")
    p.add_argument("project", help=f"project file to write ({SUFFIX})")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scene", help="scene.json (docs/formats.md)")
    src.add_argument("--product", help="a JAXA product folder (CEOS or GeoTIFF 1B2)")
    p.add_argument("--points", help="ground points CSV (id,E,N,H[,kind,height,...])")
    p.add_argument("--measurements", help="image measurements CSV (id,view,x,y)")
    p.add_argument("--crs", help="CRS of the ground points if not the scene's (e.g. EPSG:4326)")
    p.add_argument("--height", choices=HEIGHT_KINDS, help="height kind of points without a height column")
    p.add_argument("--geoid", help="geoid: a number (constant undulation, m), a grid file, or 'auto'")
    p.add_argument("--force", action="store_true", help="overwrite an existing project")
    p.set_defaults(func=run)


def geoid_setting(value: str | None, scene) -> dict:
    if value is None:
        return {"kind": "constant", "value": scene.geoid_undulation_m or 0.0}
    if value == "auto":
        return {"kind": "auto", "value": scene.geoid_undulation_m or 0.0}
    try:
        return {"kind": "constant", "value": float(value)}
    except ValueError:
        if not Path(value).is_file():
            raise InputError("geoid grid not found", value) from None
        return {"kind": "grid", "path": str(Path(value).resolve())}


def create(project_path, scene_path, points=None, measurements=None, *, crs=None, height=None,
           geoid=None, force=False) -> Project:
    """Build and save a project (the ``new`` command as a function)."""
    project_path = Path(project_path)
    if project_path.exists() and not force:
        raise InputError("already exists (use --force to overwrite)", project_path)
    scene = read_scene(scene_path)
    project = Project(scene, str(Path(scene_path).resolve()), geoid=geoid_setting(geoid, scene))
    pts = read_ground_points(points, crs=crs, to_crs=scene.crs, height=height) if points else []
    ms = read_measurements(measurements, views=list(scene.views)) if measurements else []
    project.load(pts, ms)
    save_project(project, project_path)
    return project


def run(args) -> int:
    scene_path = args.scene
    if args.product:
        from prismstation.io.products import write_scene_for_product
        scene_path = write_scene_for_product(args.product, Path(args.project).parent)
    project = create(args.project, scene_path, args.points, args.measurements, crs=args.crs,
                     height=args.height, geoid=args.geoid, force=args.force)
    n_ms = len(project.measurements)
    kinds = [p.kind for p in project.points.values()]
    print(f"{args.project}: {kinds.count('GCP')} GCP, {kinds.count('ICP')} ICP, "
          f"{kinds.count('TIE')} tie points, {n_ms} measurements")
    return 0
