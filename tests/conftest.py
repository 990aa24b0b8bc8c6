import os
import sys

import numpy as np
import pytest
import trimesh

sys.path.insert(0, os.path.dirname(__file__))

import sonar_embree as se  # noqa: E402

H = 10.0  # sonar altitude of the reference cases, m

#: Tests that take a second or more on the 2-core machine (``pytest --durations``), marked ``slow``: the quick
#: tier, ``python -m pytest -q -m "not slow"``, leaves them out (README, "Tests").
SLOW = frozenset({
    "test_receiver_arrays.py::test_off_line_elements_hear_the_lattice_through_their_own_elevation_pattern",
    "test_replay.py::test_a_calibrated_replay_has_the_records_texture_statistics",
    "test_replay.py::test_fit_pulse_recovers_a_hidden_pulse_length",
    "test_replay.py::test_fit_pulse_says_when_the_record_lies_beyond_its_pulses",
    "test_replay.py::test_a_fit_is_saved_as_a_device_file_that_render_survey_and_replay_take",
    "test_replay.py::test_fit_texture_recovers_a_hidden_k_distribution_shape",
    "test_curved_swell.py::test_a_swell_over_a_profile_matches_the_ray_shooting_quadrature",
    "test_curved_swell.py::test_msis_and_the_forward_looking_sonar_take_a_swell",
    "test_replay.py::test_fit_beam_recovers_the_records_elevation_pattern_and_gain",
    "test_replay.py::test_a_long_lines_fit_simulates_runs_across_its_altitudes_and_recovers_the_class_and_gain",
    "test_replay.py::test_a_joint_fit_recovers_tilt_width_class_gain_and_texture",
    "test_sas_records.py::test_at_quality_1_a_hole_is_as_deep_as_the_closed_form_makes_it",
    "test_sas_records.py::test_a_cubes_shadow_is_as_deep_as_the_closed_form_makes_it",
    "test_sas_records.py::test_with_uniform_phase_centres_and_weighting_a_hole_is_over_20_db_deep",
    "test_replay.py::test_a_device_files_beam_pulse_and_gain_come_back_through_its_decimation",
    "test_small_slope.py::test_the_small_slope_integral_against_mpmaths_oscillatory_quadrature",
    "test_small_slope.py::test_sigma_is_recovered_from_a_flat_floor_record",
    "test_small_slope.py::test_the_carriers_table_is_within_two_hundredths_of_a_db_of_the_model",
    "test_docs.py::test_the_site_builds_without_warnings_and_has_every_section",
    "test_docs.py::test_every_module_has_an_api_page",
    "test_docs.py::test_every_figure_script_is_in_the_gallery_with_its_figures",
    "test_objects_seen.py::test_a_ball_at_shallow_depression_is_seen_in_every_ping",
    "test_objects_seen.py::test_sphere_echo_follows_the_two_way_pattern_in_every_ping",
    "test_multipath.py::test_mixed_legs_with_each_rays_own_layout_matches_naive",
    "test_objects_seen.py::test_a_midwater_box_in_a_profile_starts_at_its_closed_form_arrival",
    "test_scripts.py::test_bench_objects_script_reports_time_against_object_count_and_its_error",
    "test_scripts.py::test_bench_swell_objects_script_reports_ms_per_ping_with_and_without_balls",
    "test_scripts.py::test_bench_chirp_script_reports_the_chirp_beside_cw",
    "test_scripts.py::test_realism_figure_shows_heavier_tails_than_todays_line",
    "test_scripts.py::test_sas_figure_resolves_the_mine_that_the_side_scan_blurs",
    "test_speckle_coherence.py::test_adjacent_pings_are_as_coherent_as_a_displaced_aperture",
    "test_batch.py::test_batch_output_equals_a_direct_simulation",
    "test_objects_seen.py::test_fls_spheres_peak_in_their_nearest_beam_at_the_closed_form_level",
    "test_xtf_header.py::test_shipped_side_scan_configs_write_latitude_and_longitude",
    "test_curved_surface.py::test_each_surface_path_starts_within_a_sample_of_the_quadrature",
    "test_device_records.py::test_a_flat_floors_mosaic_is_uniform_across_range_and_the_overlap",
    "test_curved_surface.py::test_surface_paths_in_a_profile_match_the_ray_map_quadrature",
    "test_gaussian_beam.py::test_a_side_scan_with_a_gaussian_beam_against_quadrature",
    "test_sonar_types.py::test_a_surface_over_a_profile_adds_multipath_only_after_its_curved_onset",
    "test_bathymetry.py::test_a_short_pair_unwraps_a_long_baseline",
    "test_objects_seen.py::test_aimed_rays_are_deterministic_across_blocks_and_cost_nothing_without_objects",
    "test_xtf_header.py::test_the_demos_xtf_has_latitude_and_longitude",
    "test_bathymetry.py::test_soundings_above_the_sonar_are_left_out_and_said",
    "test_survey_guards.py::test_labels_can_be_left_out_and_the_sediment_chosen",
    "test_replay.py::test_the_projects_own_line_replays_with_its_geometry_and_levels",
    "test_survey_cli.py::test_a_survey_toml_gives_the_same_keywords_and_refuses_unknown_keys",
    "test_survey_guards.py::test_a_ships_gps_log_flies_at_a_depth_or_an_altitude",
    "test_refraction.py::test_speckle_in_a_profile_averages_to_the_expected_record",
    "test_replay.py::test_a_line_over_a_sloping_scene_replays_with_its_geometry",
    "test_beams.py::test_square_echo_sounder_level_against_quadrature",
    "test_survey_guards.py::test_a_device_file_is_a_survey_device",
    "test_scripts.py::test_bench_speckle_coherence_script_reports_the_correlation_against_its_closed_form",
    "test_sas_records.py::test_object_masks_sit_where_the_sas_image_shows_the_object",
    "test_sas_records.py::test_a_flat_floors_image_is_fully_developed_speckle",
    "test_sas_records.py::test_a_hole_in_the_floor_is_imaged_darker_than_the_floor",
    "test_replay.py::test_fit_recovers_a_hidden_clutter_density_with_the_class",
    "test_receiver_band.py::test_noise_power_per_sample_is_nl_minus_di_plus_the_receivers_band",
    "test_replay.py::test_fit_recovers_a_hidden_gain_and_sediment_class",
    "test_clutter.py::test_scintillation_index_is_the_compound_poisson_closed_form",
    "test_volume.py::test_the_floor_cuts_the_column_as_its_directions_meet_it",
    "test_directivity.py::test_square_piston_di_is_its_pattern_integral",
    "test_replay.py::test_replay_over_a_dem_from_the_command_line",
    "test_survey_cli.py::test_a_survey_from_a_dem_and_a_nav_log_runs_from_the_cli",
    "test_survey_cli.py::test_a_planned_survey_covers_a_polygon",
    "test_survey_guards.py::test_a_survey_killed_at_any_point_resumes_with_the_same_command",
    "test_device_records.py::test_every_presets_survey_has_a_dark_water_column",
    "test_journeys.py::test_demo_journey",
    "test_journeys.py::test_survey_journey",
    "test_journeys.py::test_render_journey",
    "test_scripts.py::test_survey_xtf_figure_shows_the_tvgs_dark_water_column_beside_the_agc",
    "test_hostile_folders.py::test_a_users_file_at_any_output_name_survives_overwrite",
    "test_hostile_folders.py::test_dot_prefixed_user_files_are_never_touched",
    "test_hostile_folders.py::test_the_input_as_an_output_is_refused",
    "test_objects_seen.py::test_a_small_ball_in_a_sound_speed_profile_is_seen_in_every_ping",
    "test_objects_seen.py::test_surface_paths_of_a_small_ball_follow_the_image_method",
    "test_refraction.py::test_arc_kernels_with_each_rays_own_layout_give_the_fans_bits",
    "test_objects_seen.py::test_fls_sphere_swept_across_a_beam_traces_the_array_factor",
    "test_objects_seen.py::test_a_small_objects_labels_and_coco_box_cover_every_ping_of_its_echo",
    "test_batch.py::test_jobs_are_the_product_of_scenes_trajectories_vary_and_seeds",
    "test_batch.py::test_killed_batch_resumes_to_the_same_files",
    "test_batch.py::test_two_workers_on_a_scheduler_give_identical_files",
    "test_batch.py::test_a_real_scheduler_and_two_worker_processes_give_identical_files",
    "test_stream.py::test_a_line_on_two_worker_processes_gives_the_same_bytes_and_resumes",
    "test_survey_cli.py::test_a_survey_on_two_worker_processes_writes_the_same_line",
    "test_dem.py::test_mosaic_of_streamed_stores_equals_the_in_memory_one",
    "test_errors.py::test_console_script_prints_one_line_without_traceback",
    "test_first_hour.py::test_a_million_row_trajectory_csv_is_refused_in_one_line",
    "test_first_hour.py::test_a_second_batch_of_the_same_folder_is_refused_while_the_first_runs",
    "test_first_hour.py::test_batch_is_quiet_on_success",
    "test_first_hour.py::test_ctrl_c_prints_one_line_and_leaves_nothing",
    "test_first_hour.py::test_disk_full_leaves_the_old_outputs_and_names_the_path",
    "test_first_hour.py::test_example_sweeps_check_and_cover_their_purpose",
    "test_first_hour.py::test_failed_batch_leaves_no_folder_that_refuses_a_rerun",
    "test_first_hour.py::test_multi_object_obj_sweep_without_instances_writes_coco",
    "test_first_hour.py::test_readme_api_snippet_runs_from_a_temporary_folder",
    "test_first_hour.py::test_resume_refuses_changed_mesh_contents_and_attitude",
    "test_first_hour.py::test_ten_million_pings_are_refused_at_once_with_the_estimate",
    "test_flat_floor.py::test_mean_line_matches_analytic_within_half_db",
    "test_flat_floor.py::test_reference_quadrature_reproduces_physics_md_numbers",
    "test_forward_looking.py::test_beamformed_speckle_is_fully_developed_in_either_band",
    "test_forward_looking.py::test_flat_floor_boresight_beam_matches_quadrature",
    "test_io.py::test_a_full_disk_is_one_line_naming_the_file_not_its_temporary",
    "test_law_recovery.py::test_composite_sigma_recovered",
    "test_law_recovery.py::test_kirchhoff_sigma_recovered_including_the_nadir_peak",
    "test_law_recovery.py::test_lambert_sigma_recovered",
    "test_law_recovery.py::test_tabulated_sigma_recovered",
    "test_laws.py::test_kirchhoff_flat_floor_against_quadrature",
    "test_motion.py::test_motion_during_the_ping_shifts_a_point_target_by_v_tau_over_2",
    "test_msis.py::test_flat_floor_matches_the_quadrature_of_eq1",
    "test_multipath.py::test_a_flat_swell_mesh_moves_during_the_ping_as_the_image_method_does",
    "test_multipath.py::test_four_path_image_sum_matches_quadrature",
    "test_multipath.py::test_moving_during_the_ping_turns_every_path_s_receive_beam",
    "test_multipath.py::test_speckle_with_a_surface_averages_to_the_expected_four_paths",
    "test_paper_scenes.py::test_example_configs_load_and_match_the_library",
    "test_record_cli.py::test_cli_help_explains_options",
    "test_record_cli.py::test_cli_render_example_config",
    "test_record_cli.py::test_demo_command_writes_png",
    "test_refraction.py::test_expected_intensity_matches_the_ray_map_quadrature",
    "test_refraction.py::test_first_arrival_per_launch_angle_against_the_ray_map",
    "test_scripts.py::test_bench_script_writes_report_and_plot",
    "test_scripts.py::test_detection_dataset_script_writes_a_coco_dataset",
    "test_scripts.py::test_device_figure_shows_noise_where_the_unit_source_record_is_silent",
    "test_scripts.py::test_msis_figure_script_draws_both_scans",
    "test_scripts.py::test_multipath_figure_shows_the_surface_paths",
    "test_scripts.py::test_paper_modes_script_writes_every_mode",
    "test_stream.py::test_a_whole_record_on_two_worker_processes_has_simulates_bits",
    "test_record_cli.py::test_cli_render_on_two_workers_writes_the_same_files",
    "test_scripts.py::test_physics_plots_script_writes_beam_pattern_and_ping",
    "test_scripts.py::test_refraction_figure_ends_the_floor_at_the_ray_maps_shadow_edge",
    "test_scripts.py::test_seafloor_gallery_orders_the_presets_and_draws_sigma",
    "test_scripts.py::test_shipwreck_script_shows_highlight_shadow_texture_and_the_bend",
    "test_scripts.py::test_survey_script_writes_georeferenced_lines_mosaic_and_truth",
    "test_sonar_types.py::test_sound_speed_profile_bends_the_rays_and_a_uniform_one_does_not",
    "test_sonar_types.py::test_speckle_is_fully_developed",
    "test_stream.py::test_a_full_disk_gives_one_line_and_the_resume_is_exact",
    "test_texture.py::test_k_texture_scintillation_index_and_mean",
})


def pytest_collection_modifyitems(items):
    for item in items:
        if f"{item.path.name}::{item.originalname}" in SLOW:
            item.add_marker(pytest.mark.slow)


def flat_scene(**material):
    return se.Scene().add(se.seafloor.flat(size_m=(400, 200), z_m=0.0),
                          material=se.Material(**material), label="seafloor")


def line_along_x(n_pings=3, z=H, length=2.0):
    """Pings heading +x (starboard towards −y) at altitude z, stop-and-hop (the model of the closed forms)."""
    return se.Trajectory.line(start=(-length / 2, 0.0, z), end=(length / 2, 0.0, z), n_pings=n_pings).stop_and_hop()


def box(extents, center):
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(center)
    return m


@pytest.fixture(scope="session")
def flat_record():
    """Default sonar, 100 µs rectangular CW, flat floor 10 m below, speckle-free."""
    return se.simulate(flat_scene(), line_along_x(), se.Sonar(), se.Pulse.cw(duration_s=100e-6, taper=0.0),
                       speckle=False, seed=0)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def facing_plate(slant_range_m=20.0, size_m=0.3, altitude_m=H, tilt_deg=20.0):
    """A square plate on the starboard boresight of a sonar at (0, 0, altitude) heading +x, facing it."""
    d = np.radians(tilt_deg)
    look = np.array([0.0, -np.cos(d), -np.sin(d)])
    centre = np.array([0.0, 0.0, altitude_m]) + slant_range_m * look
    a = np.array([1.0, 0.0, 0.0])
    b = np.cross(look, a)
    s = size_m / 2
    v = np.array([centre - a * s - b * s, centre + a * s - b * s, centre + a * s + b * s, centre - a * s + b * s])
    m = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    if np.dot(m.face_normals[0], look) > 0:
        m.invert()
    return m


def decoy_above(traj, height_m=5.0):
    """A 0.2 m cube ``height_m`` above the first ping: within range of the sonar (so a scene whose surfaces
    all lie beyond the window is not refused as "nothing in range") but behind every side-scan beam."""
    return box((0.2, 0.2, 0.2), traj.positions_m[0] + np.array([0.0, 0.0, height_m]))


def write_anchor_config(tmp_path, sonar_extra="", env=""):
    """The shipped anchor-mine config in ``tmp_path`` with lines added to its [sonar] and [environment] tables."""
    with open(se.assets.path("anchor_mine.toml"), encoding="utf-8") as fh:
        text = fh.read()
    text = text.replace("path = \"asset:anchor_mine.obj\"", f"path = \"{se.assets.path('anchor_mine.obj')}\"")
    text = text.replace("[environment]", "[environment]\n" + env, 1).replace("[sonar]", "[sonar]\n" + sonar_extra, 1)
    p = tmp_path / "run.toml"
    p.write_text(text)
    return p
