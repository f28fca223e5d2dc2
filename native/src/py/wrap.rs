//! Bindings of [`crate::wrap`]: `wrap_template`, `propose_pairs`, `carry_shapes`, `bind_to_surface`,
//! `look_at_keys`.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;

use super::arrays;
use super::errors::py_err;
use super::run::{detached, detached_with_progress};
use super::settings::settings as read_settings;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{to_f64, unit};
use crate::rig::RigView;
use crate::wrap::looks::look_at_keys as run_looks;
use crate::wrap::{bind, bind_facing_normals, carry_shapes as run_carry, propose_pairs as run_propose, wrap_template as run_wrap, AddedCurve, CarryParams, PointPairs, TemplateCurve, WrapParams};

/// wrap_template(template_neutral, template_triangles, character_neutral, character_triangles,
///               template_points, character_points, settings=None, *, progress=None)
///     -> (wrapped float32 (Nt, 3) in the character's space, report dict)
///
/// `settings`: a dict onto [`WrapParams`] (None: `default_settings("wrap")`): `fit`
/// (stiffness, iterations, landmark_weight, max_angle_degrees, max_distance, rim_weight,
/// tolerance), `align_only` and `ignore_symmetry` (fit as if the meshes were not
/// mirror-symmetric; the report's `symmetry` says whether the fit was); an unknown key is an
/// InvalidInputError naming it.
/// `template_points`, `character_points`: float32 (P, 3) point pairs in each mesh's own
/// space (P = 0 for an alignment from the principal axes).
#[pyfunction]
#[pyo3(signature = (template_neutral, template_triangles, character_neutral, character_triangles, template_points,
                    character_points, settings=None, *, progress=None))]
#[allow(clippy::too_many_arguments)]
fn wrap_template<'py>(
    py: Python<'py>,
    template_neutral: PyReadonlyArray2<'py, f32>,
    template_triangles: PyReadonlyArray2<'py, i32>,
    character_neutral: PyReadonlyArray2<'py, f32>,
    character_triangles: PyReadonlyArray2<'py, i32>,
    template_points: PyReadonlyArray2<'py, f32>,
    character_points: PyReadonlyArray2<'py, f32>,
    settings: Option<Bound<'py, PyAny>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let params: WrapParams = read_settings(py, settings.as_ref(), "wrap")?;
    let template = arrays::points(&template_neutral, "template_neutral").map_err(py_err(py))?;
    let character = arrays::points(&character_neutral, "character_neutral").map_err(py_err(py))?;
    let template_tris = arrays::triangles(&template_triangles).map_err(py_err(py))?;
    let character_tris = arrays::triangles(&character_triangles).map_err(py_err(py))?;
    let pairs = PointPairs {
        template: arrays::points(&template_points, "template_points").map_err(py_err(py))?,
        character: arrays::points(&character_points, "character_points").map_err(py_err(py))?,
    };
    let fit = &params.fit;
    if fit.stiffness.is_empty() || fit.stiffness.iter().any(|&a| !(a > 0.0 && a.is_finite())) || fit.iterations == 0 {
        return Err(py_err(py)(crate::invalid!("stiffness must be a non-empty list of positive numbers and iterations at least 1")));
    }
    let wrap = detached_with_progress(py, progress.as_ref(), |progress| {
        run_wrap(template, &template_tris, character, &character_tris, pairs, &params, progress)
    })?;
    let n = wrap.wrapped.len();
    let flat: Vec<f32> = wrap.wrapped.into_iter().flatten().collect();
    let array = PyArray1::from_vec(py, flat).reshape([n, 3])?;
    Ok((array.into_any(), arrays::to_python(py, &wrap.report)?))
}

/// propose_pairs(template_neutral, template_deltas, template_triangles, names, character_neutral,
///               character_triangles, *, progress=None) -> dict
///
/// Point pairs found on both heads (eye and mouth corners, nose tip, chin): `pairs`
/// (each `name`, `template_vertex`, `character_vertex`, `template`, `character`: vertices and
/// their rest points), `missing` (features not found on
/// both), the alignment they were found through (`similarity`, `alignment_distance`), both
/// heads' front and up, `warnings`. The template's keys (float32 (K, Nt, 3)) and names tell
/// where its face is and which way it looks.
#[pyfunction]
#[pyo3(signature = (template_neutral, template_deltas, template_triangles, names, character_neutral, character_triangles, *, progress=None))]
#[allow(clippy::too_many_arguments)]
fn propose_pairs<'py>(
    py: Python<'py>,
    template_neutral: PyReadonlyArray2<'py, f32>,
    template_deltas: PyReadonlyArray3<'py, f32>,
    template_triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    character_neutral: PyReadonlyArray2<'py, f32>,
    character_triangles: PyReadonlyArray2<'py, i32>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let template = arrays::points(&template_neutral, "template_neutral").map_err(py_err(py))?;
    let (deltas, _) = arrays::deltas(&template_deltas, template.len()).map_err(py_err(py))?;
    let template_tris = arrays::triangles(&template_triangles).map_err(py_err(py))?;
    let character = arrays::points(&character_neutral, "character_neutral").map_err(py_err(py))?;
    let character_tris = arrays::triangles(&character_triangles).map_err(py_err(py))?;
    let proposal = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(template, deltas, &template_tris, &names)?;
        run_propose(&rig, character, &character_tris, progress)
    })?;
    arrays::to_python(py, &proposal)
}

/// carry_shapes(wrapped_neutral, template_triangles, template_deltas, character_neutral,
///              character_triangles, settings=None, *, template_added=None, template_crossing=None,
///              template_neutral=None, template_shapes=None, progress=None)
///     -> (deltas float32 (K, Nc, 3), report dict)
///
/// `settings`: a dict onto [`CarryParams`] (None: `default_settings("carry")`):
/// static_fraction, anchor_length, max_angle_degrees, collision_pass, collision_margin,
/// collision_stiffness, collision_tolerance, symmetrize; an unknown key is an
/// InvalidInputError naming it.
/// `template_neutral` (float32 (Nt, 3), the template's rest in the wrapped template's vertex
/// order) makes the carry symmetric when template and character are: each carried shape is
/// averaged with the mirror of its partner's before the collision pass; the report's
/// `symmetry` says whether it was, and per mirror pair of shapes the worst vertex's miss
/// (`symmetrize: false` only measures them).
/// `template_shapes` (float32 (K, Nt, 3), the template's own deltas in its own space, the
/// shapes of `template_deltas` in their order; with `template_neutral`) gives each character
/// piece matching a template piece the template piece's own motion mapped by the similarity
/// that placed it (an eyeball turns as the template's does, the teeth follow the jaw).
/// `template_added` and `template_crossing` (float64 (K, 2) each, given together: per shape,
/// the intersection curve the template's own shape adds to the template's neutral and its
/// whole curve, inside one piece and between pieces, in the character's units: the transfer
/// report rows' `template_added` and `template_crossing`) have every carried shape judged on
/// the character (the report's `penetration`: the neutral's and each shape's, and per shape
/// the `excess` over what the template's allows), and with `collision_pass` turn on the
/// collision pass: a carried shape adding more to the character's neutral is held off the
/// surfaces it goes through (`collision_margin` x the local edge length) and re-solved; the
/// report's `collisions` has one row per shape.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (wrapped_neutral, template_triangles, template_deltas, character_neutral, character_triangles,
                    settings=None, *, template_added=None, template_crossing=None, template_neutral=None, template_shapes=None,
                    progress=None))]
fn carry_shapes<'py>(
    py: Python<'py>,
    wrapped_neutral: PyReadonlyArray2<'py, f32>,
    template_triangles: PyReadonlyArray2<'py, i32>,
    template_deltas: PyReadonlyArray3<'py, f32>,
    character_neutral: PyReadonlyArray2<'py, f32>,
    character_triangles: PyReadonlyArray2<'py, i32>,
    settings: Option<Bound<'py, PyAny>>,
    template_added: Option<PyReadonlyArray2<'py, f64>>,
    template_crossing: Option<PyReadonlyArray2<'py, f64>>,
    template_neutral: Option<PyReadonlyArray2<'py, f32>>,
    template_shapes: Option<PyReadonlyArray3<'py, f32>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let params: CarryParams = read_settings(py, settings.as_ref(), "carry")?;
    let parts = |array: &PyReadonlyArray2<'py, f64>, name: &str| -> PyResult<Vec<AddedCurve>> {
        let view = array.as_array();
        if view.ncols() != 2 {
            return Err(py_err(py)(crate::invalid!("{name} must have 2 columns (inside, between), got {}", view.ncols())));
        }
        Ok(view.rows().into_iter().map(|row| AddedCurve { inside: row[0], between: row[1] }).collect())
    };
    let template_curve: Option<Vec<TemplateCurve>> = match (&template_added, &template_crossing) {
        (None, None) => None,
        (Some(added), Some(crossing)) => {
            let (added, crossing) = (parts(added, "template_added")?, parts(crossing, "template_crossing")?);
            if added.len() != crossing.len() {
                return Err(py_err(py)(crate::invalid!("template_added has {} rows but template_crossing {}", added.len(), crossing.len())));
            }
            Some(added.into_iter().zip(crossing).map(|(added, crossing)| TemplateCurve { added, crossing }).collect())
        }
        _ => return Err(py_err(py)(crate::invalid!("give template_added and template_crossing together (the transfer report rows' own)"))),
    };
    let wrapped = arrays::points(&wrapped_neutral, "wrapped_neutral").map_err(py_err(py))?;
    let (deltas, k) = arrays::deltas(&template_deltas, wrapped.len()).map_err(py_err(py))?;
    let template_tris = arrays::triangles(&template_triangles).map_err(py_err(py))?;
    let character = arrays::points(&character_neutral, "character_neutral").map_err(py_err(py))?;
    let character_tris = arrays::triangles(&character_triangles).map_err(py_err(py))?;
    let template_rest = template_neutral.as_ref().map(|t| arrays::points(t, "template_neutral")).transpose().map_err(py_err(py))?;
    let template_own = template_shapes.as_ref().map(|t| arrays::deltas(t, wrapped.len())).transpose().map_err(py_err(py))?;
    if template_own.as_ref().is_some_and(|(_, own_k)| *own_k != k) {
        return Err(py_err(py)(crate::invalid!("template_shapes has {} shapes but template_deltas {k}", template_own.as_ref().map_or(0, |t| t.1))));
    }
    let result = detached_with_progress(py, progress.as_ref(), |progress| {
        run_carry(wrapped, &template_tris, deltas, character, &character_tris, template_curve.as_deref(), template_rest, template_own.map(|t| t.0), &params, progress)
    })?;
    let nc = character.len();
    let flat: Vec<f32> = result.deltas.iter().flatten().copied().collect();
    let array = PyArray1::from_vec(py, flat).reshape([k, nc, 3])?;
    Ok((array.into_any(), arrays::to_python(py, &result)?))
}

/// bind_to_surface(points, surface_neutral, surface_triangles, normals=None, max_angle_degrees=60.0)
///     -> (triangle int32 (N,), barycentric float32 (N, 3), distance float32 (N,))
///
/// Each point's closest point on the surface: for comparisons (barycentric and nearest-vertex
/// copies, mirror images) and pictures. With `normals` (float32 (N, 3), one per point) the
/// closest among the triangles facing within `max_angle_degrees` of the point's normal (the
/// plain closest point where none does), as the carry binds: a point on one lip never lands
/// on the other lip it touches.
#[pyfunction]
#[pyo3(signature = (points, surface_neutral, surface_triangles, normals=None, max_angle_degrees=60.0))]
fn bind_to_surface<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    surface_neutral: PyReadonlyArray2<'py, f32>,
    surface_triangles: PyReadonlyArray2<'py, i32>,
    normals: Option<PyReadonlyArray2<'py, f32>>,
    max_angle_degrees: f64,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let query = arrays::points(&points, "points").map_err(py_err(py))?;
    let surface = arrays::points(&surface_neutral, "surface_neutral").map_err(py_err(py))?;
    let tris = arrays::triangles(&surface_triangles).map_err(py_err(py))?;
    let normals = normals.as_ref().map(|n| arrays::points(n, "normals")).transpose().map_err(py_err(py))?;
    let hits = detached(py, || {
        crate::rig::validate_points(query, "points")?;
        crate::rig::validate_points(surface, "surface_neutral")?;
        crate::rig::validate_triangle_indices(surface.len(), &tris)?;
        if tris.is_empty() {
            return Err(crate::invalid!("the surface has no faces"));
        }
        let surface: Vec<[f64; 3]> = surface.iter().map(to_f64).collect();
        let query: Vec<[f64; 3]> = query.iter().map(to_f64).collect();
        let bvh = TriangleBvh::build(&surface, &tris);
        let Some(normals) = normals else { return Ok(bind(&query, &bvh)) };
        if normals.len() != query.len() {
            return Err(crate::invalid!("normals has {} rows for {} points", normals.len(), query.len()));
        }
        crate::rig::validate_points(normals, "normals")?;
        if !(0.0..=180.0).contains(&max_angle_degrees) {
            return Err(crate::invalid!("max_angle_degrees must be within 0-180, got {max_angle_degrees}"));
        }
        let normals: Vec<[f64; 3]> = normals.iter().map(|n| unit(to_f64(n)).unwrap_or([0.0; 3])).collect();
        Ok(bind_facing_normals(&query, &normals, &surface, &tris, &bvh, max_angle_degrees.to_radians().cos()))
    })?;
    let n = hits.len();
    let triangle: Vec<i32> = hits.iter().map(|h| h.triangle as i32).collect();
    let barycentric: Vec<f32> = hits.iter().flat_map(|h| h.barycentric.map(|x| x as f32)).collect();
    let distance: Vec<f32> = hits.iter().map(|h| h.distance_squared.sqrt() as f32).collect();
    Ok((
        PyArray1::from_vec(py, triangle).into_any(),
        PyArray1::from_vec(py, barycentric).reshape([n, 3])?.into_any(),
        PyArray1::from_vec(py, distance).into_any(),
    ))
}

/// look_at_keys(template_neutral, template_deltas, template_triangles, names, wrapped_neutral,
///              wrapped_deltas, character_neutral, character_triangles, character_deltas,
///              truth_deltas=None) -> dict
///
/// Where riggers look first, per carried key ([`crate::wrap::looks`]): `shapes`, one row per
/// name (`turned_over` and `turned_over_share`, `roughness`, `copy_roughness`, `truth_roughness`; a blink's
/// `eye_gap`, `eyes_close` and `lid_turning`; jawOpen's `mouth_opening` and `lip_turning`;
/// mouthClose's `mouth_closing`; each beside the template's own as `template_*`), and the
/// `openings` found on the template (margins as template vertices). `template_*`: the
/// template's rest and own keys float32 (K, Nt, 3) in the order of `names`; `wrapped_*`:
/// where the fit put each template vertex and the keys the carry carried; `character_deltas`
/// (and `truth_deltas`, the same-topology truth sampled there) float32 (K, Nc, 3).
#[pyfunction]
#[pyo3(signature = (template_neutral, template_deltas, template_triangles, names, wrapped_neutral, wrapped_deltas,
                    character_neutral, character_triangles, character_deltas, truth_deltas=None))]
#[allow(clippy::too_many_arguments)]
fn look_at_keys<'py>(
    py: Python<'py>,
    template_neutral: PyReadonlyArray2<'py, f32>,
    template_deltas: PyReadonlyArray3<'py, f32>,
    template_triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    wrapped_neutral: PyReadonlyArray2<'py, f32>,
    wrapped_deltas: PyReadonlyArray3<'py, f32>,
    character_neutral: PyReadonlyArray2<'py, f32>,
    character_triangles: PyReadonlyArray2<'py, i32>,
    character_deltas: PyReadonlyArray3<'py, f32>,
    truth_deltas: Option<PyReadonlyArray3<'py, f32>>,
) -> PyResult<Bound<'py, PyAny>> {
    let template = arrays::points(&template_neutral, "template_neutral").map_err(py_err(py))?;
    let (deltas, _) = arrays::deltas(&template_deltas, template.len()).map_err(py_err(py))?;
    let template_tris = arrays::triangles(&template_triangles).map_err(py_err(py))?;
    let wrapped = arrays::points(&wrapped_neutral, "wrapped_neutral").map_err(py_err(py))?;
    let (wrapped_keys, _) = arrays::deltas(&wrapped_deltas, wrapped.len()).map_err(py_err(py))?;
    let character = arrays::points(&character_neutral, "character_neutral").map_err(py_err(py))?;
    let character_tris = arrays::triangles(&character_triangles).map_err(py_err(py))?;
    let (keys, _) = arrays::deltas(&character_deltas, character.len()).map_err(py_err(py))?;
    let truth = truth_deltas.as_ref().map(|t| arrays::deltas(t, character.len())).transpose().map_err(py_err(py))?;
    let looks = detached(py, || {
        let rig = RigView::new(template, deltas, &template_tris, &names)?;
        run_looks(&rig, wrapped, wrapped_keys, character, &character_tris, keys, truth.map(|t| t.0))
    })?;
    arrays::to_python(py, &looks)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(look_at_keys, m)?)?;
    m.add_function(wrap_pyfunction!(wrap_template, m)?)?;
    m.add_function(wrap_pyfunction!(propose_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(carry_shapes, m)?)?;
    m.add_function(wrap_pyfunction!(bind_to_surface, m)?)
}
