// mocapbench's C shim around ACL 2.1 (the Animation Compression Library, github.com/nfrechette/acl).
//
// Compiled on first use by mocapbench/codecs/acl/build.py against the user's ACL + rtm headers
// (header-only, MIT); loaded through ctypes. Every function returns 0 on success or writes one line into
// `error` (at most `error_size` bytes, NUL-terminated) and returns a non-zero code. No C++ exception or
// ACL assert crosses this boundary; a buffer is validated (size field, tag, version, hash: ACL's
// `compressed_tracks::is_valid(true)`) before any decompression reads it.
//
// Layout of the arrays (all float32, little-endian, C order):
//   rotations    (F, J, 4)  local rotations, scalar-last quaternions (x, y, z, w)
//   translations (F, J, 3)  local translations, cm (the root's position; each other joint's translation in its
//                           parent's frame: its bone offset where it does not move)
//   scales       (F, J, 3)  local scales, unitless (NULL: 1 everywhere)
//   parents      (J,)       int32 parent index, -1 for the root

#include <acl/compression/compress.h>
#include <acl/compression/pre_process.h>
#include <acl/compression/track_array.h>
#include <acl/compression/transform_error_metrics.h>
#include <acl/core/ansi_allocator.h>
#include <acl/core/compressed_tracks.h>
#include <acl/decompression/decompress.h>
#include <acl/version.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <new>

namespace
{
	acl::ansi_allocator g_allocator;

	void set_error(char* error, uint32_t error_size, const char* message)
	{
		if (error != nullptr && error_size > 0)
			std::snprintf(error, error_size, "%s", message);
	}

	// Decompression settings that accept every rotation and translation format (the config may pick the
	// full-precision ones), used when a buffer is not in the default variable formats.
	struct any_format_transform_settings : public acl::decompression_settings
	{
		static constexpr bool is_track_type_supported(acl::track_type8 type) { return type == acl::track_type8::qvvf; }
		static constexpr bool is_per_track_rounding_supported() { return false; }
	};

	struct pose_writer final : public acl::track_writer
	{
		float* rotations;     // (J, 4)
		float* translations;  // (J, 3)
		float* scales;        // (J, 3), or nullptr: scales are not wanted

		void RTM_SIMD_CALL write_rotation(uint32_t track_index, rtm::quatf_arg0 rotation)
		{
			rtm::quat_store(rotation, rotations + 4 * track_index);
		}

		void RTM_SIMD_CALL write_translation(uint32_t track_index, rtm::vector4f_arg0 translation)
		{
			rtm::vector_store3(translation, translations + 3 * track_index);
		}

		void RTM_SIMD_CALL write_scale(uint32_t track_index, rtm::vector4f_arg0 scale)
		{
			if (scales != nullptr)
				rtm::vector_store3(scale, scales + 3 * track_index);
		}
	};

	// An aligned copy of a caller's buffer, validated as a compressed_tracks instance.
	struct validated_buffer
	{
		void* memory = nullptr;
		const acl::compressed_tracks* tracks = nullptr;

		~validated_buffer() { std::free(memory); }

		bool load(const uint8_t* data, uint32_t size, char* error, uint32_t error_size)
		{
			constexpr uint32_t k_min_size = 64;  // raw buffer header + tracks header, rounded up
			if (data == nullptr || size < k_min_size)
			{
				set_error(error, error_size, "ACL buffer is shorter than its header");
				return false;
			}
			uint32_t declared = 0;
			std::memcpy(&declared, data, sizeof(declared));  // raw_buffer_header::size comes first
			if (declared != size)
			{
				char message[160];
				std::snprintf(message, sizeof(message), "ACL buffer declares %u bytes, found %u", declared, size);
				set_error(error, error_size, message);
				return false;
			}
			const size_t padded = (size_t(size) + 15) & ~size_t(15);
			memory = std::aligned_alloc(16, padded);
			if (memory == nullptr)
			{
				set_error(error, error_size, "out of memory copying the ACL buffer");
				return false;
			}
			std::memcpy(memory, data, size);
			const acl::compressed_tracks* candidate = static_cast<const acl::compressed_tracks*>(memory);
			const acl::error_result result = candidate->is_valid(true);
			if (result.any())
			{
				char message[200];
				std::snprintf(message, sizeof(message), "ACL buffer is invalid: %s", result.c_str());
				set_error(error, error_size, message);
				return false;
			}
			if (candidate->get_track_type() != acl::track_type8::qvvf)
			{
				set_error(error, error_size, "ACL buffer does not hold transform (qvvf) tracks");
				return false;
			}
			tracks = candidate;
			return true;
		}
	};

	bool is_default_format(const acl::compressed_tracks& tracks)
	{
		const acl::acl_impl::tracks_header& header = acl::acl_impl::get_tracks_header(tracks);
		return header.get_rotation_format() == acl::rotation_format8::quatf_drop_w_variable
			&& header.get_translation_format() == acl::vector_format8::vector3f_variable
			&& header.get_scale_format() == acl::vector_format8::vector3f_variable;
	}

	template<class settings_type>
	int decompress_with(const acl::compressed_tracks& tracks, uint32_t start, uint32_t stop, float* rotations,
		float* translations, float* scales, char* error, uint32_t error_size)
	{
		acl::decompression_context<settings_type> context;
		if (!context.initialize(tracks))
		{
			set_error(error, error_size, "ACL could not initialize a decompression context for this buffer");
			return 4;
		}
		const uint32_t num_tracks = tracks.get_num_tracks();
		const float sample_rate = tracks.get_sample_rate();
		pose_writer writer;
		for (uint32_t frame = start; frame < stop; ++frame)
		{
			writer.rotations = rotations + size_t(frame - start) * num_tracks * 4;
			writer.translations = translations + size_t(frame - start) * num_tracks * 3;
			writer.scales = scales == nullptr ? nullptr : scales + size_t(frame - start) * num_tracks * 3;
			// ACL's own error measurement samples at index / rate with the nearest-sample policy.
			context.seek(float(frame) / sample_rate, acl::sample_rounding_policy::nearest);
			context.decompress_tracks(writer);
		}
		return 0;
	}

	double cpu_seconds()
	{
		timespec now{};
		clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
		return double(now.tv_sec) + 1e-9 * double(now.tv_nsec);
	}
}

#define MCB_EXPORT __attribute__((visibility("default")))

extern "C"
{
	// ACL's version as MAJOR * 10000 + MINOR * 100 + PATCH (20100 for 2.1.0).
	MCB_EXPORT int mcb_acl_version()
	{
		return ACL_VERSION_MAJOR * 10000 + ACL_VERSION_MINOR * 100 + ACL_VERSION_PATCH;
	}

	// Compress one clip. On success *out_buffer holds a malloc'ed copy of ACL's compressed buffer
	// (free it with mcb_acl_free) and *out_size its size in bytes.
	//   level: compression_level8 (0 lowest .. 4 highest, 100 automatic)
	//   rotation_format: rotation_format8 (0 quatf_full, 2 quatf_drop_w_full, 3 quatf_drop_w_variable)
	//   translation_format: vector_format8 (0 vector3f_full, 1 vector3f_variable); scales stay variable
	//   pre_process: non-zero runs ACL's pre_process_track_list on the raw tracks first (its recommended actions,
	//     lossy, with the same qvvf error metric as the compression; optimize_looping only when optimize_loops)
	MCB_EXPORT int mcb_acl_compress(const float* rotations, const float* translations, const float* scales,
		const int32_t* parents, uint32_t num_joints, uint32_t num_frames, float sample_rate, float precision_cm,
		float shell_cm, int level, int rotation_format, int translation_format, int optimize_loops, int strip_trivial,
		int pre_process, void** out_buffer, uint32_t* out_size, char* error, uint32_t error_size)
	{
		try
		{
			*out_buffer = nullptr;
			*out_size = 0;
			acl::track_array_qvvf raw_tracks(g_allocator, num_joints);
			for (uint32_t joint = 0; joint < num_joints; ++joint)
			{
				acl::track_desc_transformf desc;
				desc.output_index = joint;
				desc.parent_index = parents[joint] < 0 ? acl::k_invalid_track_index : uint32_t(parents[joint]);
				desc.precision = precision_cm;
				desc.shell_distance = shell_cm;
				acl::track_qvvf track = acl::track_qvvf::make_reserve(desc, g_allocator, num_frames, sample_rate);
				for (uint32_t frame = 0; frame < num_frames; ++frame)
				{
					const float* q = rotations + (size_t(frame) * num_joints + joint) * 4;
					const float* t = translations + (size_t(frame) * num_joints + joint) * 3;
					const rtm::vector4f scale = scales == nullptr ? rtm::vector_set(1.0F)
						: rtm::vector_load3(scales + (size_t(frame) * num_joints + joint) * 3);
					track[frame] = rtm::qvv_set(rtm::quat_set(q[0], q[1], q[2], q[3]), rtm::vector_set(t[0], t[1], t[2]),
						scale);
				}
				raw_tracks[joint] = std::move(track);
			}
			const acl::error_result valid = raw_tracks.is_valid();
			if (valid.any())
			{
				char message[200];
				std::snprintf(message, sizeof(message), "ACL rejects the tracks: %s", valid.c_str());
				set_error(error, error_size, message);
				return 2;
			}

			acl::qvvf_transform_error_metric error_metric;
			if (pre_process != 0)
			{
				acl::pre_process_settings_t pre_settings;
				pre_settings.actions = acl::pre_process_actions::recommended;
				if (optimize_loops == 0)
					pre_settings.actions &= ~acl::pre_process_actions::optimize_looping;
				pre_settings.precision_policy = acl::pre_process_precision_policy::lossy;
				pre_settings.error_metric = &error_metric;
				const acl::error_result pre_result = acl::pre_process_track_list(g_allocator, pre_settings, raw_tracks);
				if (pre_result.any())
				{
					char message[200];
					std::snprintf(message, sizeof(message), "ACL pre-processing failed: %s", pre_result.c_str());
					set_error(error, error_size, message);
					return 2;
				}
			}

			acl::compression_settings settings = acl::get_default_compression_settings();
			settings.level = acl::compression_level8(level);
			settings.rotation_format = acl::rotation_format8(rotation_format);
			settings.translation_format = acl::vector_format8(translation_format);
			settings.optimize_loops = optimize_loops != 0;
			settings.keyframe_stripping.strip_trivial = strip_trivial != 0;
			settings.error_metric = &error_metric;

			acl::output_stats stats;
			acl::compressed_tracks* compressed = nullptr;
			const acl::error_result result = acl::compress_track_list(g_allocator, raw_tracks, settings, compressed, stats);
			if (result.any() || compressed == nullptr)
			{
				char message[200];
				std::snprintf(message, sizeof(message), "ACL compression failed: %s", result.any() ? result.c_str() : "no output");
				set_error(error, error_size, message);
				return 3;
			}
			const uint32_t size = compressed->get_size();
			void* copy = std::malloc(size);
			if (copy == nullptr)
			{
				g_allocator.deallocate(compressed, size);
				set_error(error, error_size, "out of memory copying the compressed buffer");
				return 5;
			}
			std::memcpy(copy, compressed, size);
			g_allocator.deallocate(compressed, size);
			*out_buffer = copy;
			*out_size = size;
			return 0;
		}
		catch (const std::bad_alloc&)
		{
			set_error(error, error_size, "out of memory in ACL compression");
			return 5;
		}
		catch (const std::exception& exception)
		{
			set_error(error, error_size, exception.what());
			return 6;
		}
		catch (...)
		{
			set_error(error, error_size, "unknown C++ exception in ACL compression");
			return 6;
		}
	}

	MCB_EXPORT void mcb_acl_free(void* buffer)
	{
		std::free(buffer);
	}

	// Validate a buffer and report its facts: number of tracks, samples, sample rate, formats.
	MCB_EXPORT int mcb_acl_info(const uint8_t* data, uint32_t size, uint32_t* num_tracks, uint32_t* num_samples,
		float* sample_rate, int* rotation_format, int* translation_format, char* error, uint32_t error_size)
	{
		validated_buffer buffer;
		if (!buffer.load(data, size, error, error_size))
			return 1;
		const acl::acl_impl::tracks_header& header = acl::acl_impl::get_tracks_header(*buffer.tracks);
		*num_tracks = buffer.tracks->get_num_tracks();
		*num_samples = buffer.tracks->get_num_samples_per_track();
		*sample_rate = buffer.tracks->get_sample_rate();
		*rotation_format = int(header.get_rotation_format());
		*translation_format = int(header.get_translation_format());
		return 0;
	}

	// Decompress frames [start, stop) of a buffer that holds `num_joints` tracks; writes (stop - start, J, 4)
	// rotations, (stop - start, J, 3) translations and, unless `scales` is NULL, (stop - start, J, 3) scales.
	MCB_EXPORT int mcb_acl_decompress(const uint8_t* data, uint32_t size, uint32_t num_joints, uint32_t start, uint32_t stop,
		float* rotations, float* translations, float* scales, char* error, uint32_t error_size)
	{
		validated_buffer buffer;
		if (!buffer.load(data, size, error, error_size))
			return 1;
		if (buffer.tracks->get_num_tracks() != num_joints)
		{
			char message[160];
			std::snprintf(message, sizeof(message), "ACL buffer holds %u tracks, expected %u", buffer.tracks->get_num_tracks(), num_joints);
			set_error(error, error_size, message);
			return 2;
		}
		if (start > stop)
		{
			set_error(error, error_size, "frame range start is after its stop");
			return 2;
		}
		if (is_default_format(*buffer.tracks))
			return decompress_with<acl::default_transform_decompression_settings>(*buffer.tracks, start, stop, rotations, translations, scales, error, error_size);
		return decompress_with<any_format_transform_settings>(*buffer.tracks, start, stop, rotations, translations, scales, error, error_size);
	}

	// Time the decompression of single poses, the way an engine samples a clip: one context initialized
	// once, then `repeats` seeks to pseudo-random frames of [0, num_frames) each followed by one pose decode.
	// Writes the wall and process-CPU seconds of the whole loop.
	MCB_EXPORT int mcb_acl_time_single_pose(const uint8_t* data, uint32_t size, uint32_t num_frames, uint32_t repeats,
		double* wall_s, double* cpu_s, float* checksum, char* error, uint32_t error_size)
	{
		validated_buffer buffer;
		if (!buffer.load(data, size, error, error_size))
			return 1;
		const uint32_t num_tracks = buffer.tracks->get_num_tracks();
		float* rotations = static_cast<float*>(std::malloc(size_t(num_tracks) * 4 * sizeof(float)));
		float* translations = static_cast<float*>(std::malloc(size_t(num_tracks) * 3 * sizeof(float)));
		if (rotations == nullptr || translations == nullptr || num_frames == 0)
		{
			std::free(rotations);
			std::free(translations);
			set_error(error, error_size, "out of memory or no frames");
			return 5;
		}
		acl::decompression_context<acl::default_transform_decompression_settings> context;
		if (!is_default_format(*buffer.tracks) || !context.initialize(*buffer.tracks))
		{
			std::free(rotations);
			std::free(translations);
			set_error(error, error_size, "single-pose timing needs the variable formats and a valid context");
			return 4;
		}
		pose_writer writer;
		writer.rotations = rotations;
		writer.translations = translations;
		writer.scales = nullptr;
		const float sample_rate = buffer.tracks->get_sample_rate();
		float sum = 0.0F;
		const double cpu0 = cpu_seconds();
		const auto wall0 = std::chrono::steady_clock::now();
		for (uint32_t i = 0; i < repeats; ++i)
		{
			const uint32_t frame = uint32_t((uint64_t(i) * 7919u) % num_frames);
			context.seek(float(frame) / sample_rate, acl::sample_rounding_policy::nearest);
			context.decompress_tracks(writer);
			sum += rotations[0];
		}
		const auto wall1 = std::chrono::steady_clock::now();
		*cpu_s = cpu_seconds() - cpu0;
		*wall_s = std::chrono::duration<double>(wall1 - wall0).count();
		*checksum = sum;
		std::free(rotations);
		std::free(translations);
		return 0;
	}
}
