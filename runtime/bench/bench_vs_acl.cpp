// The runtime beside ACL 2.1, measured the way ACL's decompression benchmark measures itself: one pose per call
// (every joint's local rotation and translation), forward playback, backward playback and random access, each
// with a warm cache (the clip and the context stay in the CPU caches) and a cold one (a buffer larger than the
// last-level cache is written before a timed pose, outside the timing; 48 poses spread over each clip's order are
// timed so, the others played untimed). Thread CPU time, one core.
//
//   bench_vs_acl MANIFEST [REPEATS]
//
// MANIFEST: one clip per line, "mcb_stream_path acl_buffer_path" (the .mcb stream of mcb-rot and ACL's
// compressed_tracks buffer of the same clip). Prints one line per clip and decoder:
//   decoder clip frames joints stream_bytes resident_bytes open_us fwd_warm fwd_cold bwd_warm bwd_cold rnd_warm
//   rnd_cold   (the last six in microseconds per pose, medians over REPEATS runs)
// resident_bytes: what the decoder keeps while it samples: the stream (mcb-rot: the whole .mcb; ACL: its buffer)
// plus the context (mcb-rot: mcbrot_context_size; ACL: sizeof its decompression_context).
//
// Built by mocapbench/benchmarks/runtime.py (g++ -O2, ACL's SSE4.1 minimum, the runtime compiled as C++ with the
// same flags); standard library, ACL and rtm (header-only) only.

#include <acl/core/ansi_allocator.h>
#include <acl/core/compressed_tracks.h>
#include <acl/decompression/decompress.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

extern "C" {
#include "mcbrot.h"
}

namespace
{
	double thread_seconds()
	{
		timespec now{};
		clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
		return double(now.tv_sec) + 1e-9 * double(now.tv_nsec);
	}

	std::vector<uint8_t> read_file(const char* path)
	{
		std::vector<uint8_t> data;
		FILE* file = std::fopen(path, "rb");
		if (!file)
			return data;
		std::fseek(file, 0, SEEK_END);
		long size = std::ftell(file);
		std::fseek(file, 0, SEEK_SET);
		data.resize(size_t(size));
		if (size > 0 && std::fread(data.data(), 1, size_t(size), file) != size_t(size))
			data.clear();
		std::fclose(file);
		return data;
	}

	// Written between poses in cold mode: larger than the last-level cache of the machines we run on (32 MiB).
	std::vector<uint8_t> g_flush(32u << 20);
	// Poses timed per clip and mode with a cold cache (spread evenly over the mode's order): each costs a flush.
	constexpr uint32_t k_cold_poses = 48;
	volatile uint8_t g_sink;

	void flush_caches()
	{
		for (size_t i = 0; i < g_flush.size(); i += 64)
			g_flush[i] = uint8_t(g_flush[i] + 1);
		g_sink = g_flush[g_flush.size() / 2];
	}

	struct pose_writer final : public acl::track_writer
	{
		float* rotations;
		float* translations;
		void RTM_SIMD_CALL write_rotation(uint32_t track_index, rtm::quatf_arg0 rotation)
		{
			rtm::quat_store(rotation, rotations + 4 * track_index);
		}
		void RTM_SIMD_CALL write_translation(uint32_t track_index, rtm::vector4f_arg0 translation)
		{
			rtm::vector_store3(translation, translations + 3 * track_index);
		}
		void RTM_SIMD_CALL write_scale(uint32_t, rtm::vector4f_arg0) {}
	};

	// The frame orders of the three modes.
	std::vector<uint32_t> order_of(int mode, uint32_t frames)
	{
		std::vector<uint32_t> order(frames);
		for (uint32_t i = 0; i < frames; ++i)
			order[i] = mode == 1 ? frames - 1 - i : i;
		if (mode == 2)
		{
			uint64_t state = 0x9e3779b97f4a7c15ull;
			for (uint32_t i = frames; i > 1; --i)
			{
				state = state * 6364136223846793005ull + 1442695040888963407ull;
				std::swap(order[i - 1], order[uint32_t((state >> 33) % i)]);
			}
		}
		return order;
	}

	double median(std::vector<double> values)
	{
		std::sort(values.begin(), values.end());
		return values[values.size() / 2];
	}

	// Microseconds per pose of `sample(frame)` over the order of `mode`, warm or cold, median of `repeats`.
	template<class Sample>
	double time_mode(Sample&& sample, uint32_t frames, int mode, bool cold, int repeats)
	{
		const std::vector<uint32_t> order = order_of(mode, frames);
		std::vector<double> runs;
		for (int r = 0; r < repeats; ++r)
		{
			double total = 0.0;
			if (cold)
			{
				const uint32_t every = std::max<uint32_t>(1, frames / k_cold_poses);
				uint32_t timed = 0;
				for (uint32_t i = 0; i < frames; ++i)
				{
					if (i % every != 0)
					{
						sample(order[i]);  // untimed: playback goes on (a forward player's chunk stays decoded)
						continue;
					}
					flush_caches();
					const double start = thread_seconds();
					sample(order[i]);
					total += thread_seconds() - start;
					++timed;
				}
				runs.push_back(1e6 * total / double(timed));
				continue;
			}
			else
			{
				for (uint32_t frame : order)  // one untimed pass: the caches warm
					sample(frame);
				const double start = thread_seconds();
				for (uint32_t frame : order)
					sample(frame);
				total = thread_seconds() - start;
			}
			runs.push_back(1e6 * total / double(frames));
		}
		return median(runs);
	}

	void report(const char* decoder, const char* clip, uint32_t frames, uint32_t joints, size_t stream_bytes,
		size_t resident, double open_us, const double* modes)
	{
		std::printf("%s %s %u %u %zu %zu %.3f %.4f %.4f %.4f %.4f %.4f %.4f\n", decoder, clip, frames, joints,
			stream_bytes, resident, open_us, modes[0], modes[1], modes[2], modes[3], modes[4], modes[5]);
		std::fflush(stdout);
	}

	int bench_mcbrot(const char* path, int repeats)
	{
		std::vector<uint8_t> stream = read_file(path);
		size_t size = 0;
		char message[256];
		if (mcbrot_context_size(stream.data(), stream.size(), &size, message, sizeof message) != MCBROT_OK)
		{
			std::fprintf(stderr, "%s: %s\n", path, message);
			return 1;
		}
		void* context = std::aligned_alloc(16, (size + 15) & ~size_t(15));
		std::vector<double> opens;
		for (int r = 0; r < std::max(repeats, 5); ++r)
		{
			const double start = thread_seconds();
			const int status = mcbrot_open(context, size, stream.data(), stream.size());
			opens.push_back(1e6 * (thread_seconds() - start));
			if (status != MCBROT_OK)
			{
				std::fprintf(stderr, "%s: %s\n", path, mcbrot_message(context));
				std::free(context);
				return 1;
			}
		}
		mcbrot_clip_info info;
		mcbrot_info(context, &info);
		std::vector<double> rotations(4 * size_t(info.num_joints));
		double root[3];
		double checksum = 0.0;
		auto sample = [&](uint32_t frame) {
			mcbrot_sample(context, double(frame) / info.fps, MCBROT_NEAREST, rotations.data(), root);
			checksum += rotations[0];
		};
		double modes[6];
		for (int mode = 0; mode < 3; ++mode)
			for (int cold = 0; cold < 2; ++cold)
				modes[2 * mode + cold] = time_mode(sample, info.num_frames, mode, cold != 0, repeats);
		report("mcb-rot", path, info.num_frames, info.num_joints, stream.size(), stream.size() + size, median(opens),
			modes);
		std::free(context);
		return checksum == checksum ? 0 : 1;
	}

	int bench_acl(const char* path, const char* clip, int repeats)
	{
		std::vector<uint8_t> file = read_file(path);
		if (file.size() < 64)
		{
			std::fprintf(stderr, "%s: not an ACL buffer\n", path);
			return 1;
		}
		void* memory = std::aligned_alloc(16, (file.size() + 15) & ~size_t(15));
		std::memcpy(memory, file.data(), file.size());
		const acl::compressed_tracks* tracks = static_cast<const acl::compressed_tracks*>(memory);
		if (tracks->is_valid(true).any())
		{
			std::fprintf(stderr, "%s: invalid ACL buffer\n", path);
			return 1;
		}
		acl::decompression_context<acl::default_transform_decompression_settings> context;
		std::vector<double> opens;
		for (int r = 0; r < std::max(repeats, 5); ++r)
		{
			const double start = thread_seconds();
			context.initialize(*tracks);
			opens.push_back(1e6 * (thread_seconds() - start));
		}
		const uint32_t joints = tracks->get_num_tracks(), frames = tracks->get_num_samples_per_track();
		const float rate = tracks->get_sample_rate();
		std::vector<float> rotations(4 * size_t(joints)), translations(3 * size_t(joints));
		pose_writer writer;
		writer.rotations = rotations.data();
		writer.translations = translations.data();
		double checksum = 0.0;
		auto sample = [&](uint32_t frame) {
			context.seek(float(frame) / rate, acl::sample_rounding_policy::nearest);
			context.decompress_tracks(writer);
			checksum += rotations[0];
		};
		double modes[6];
		for (int mode = 0; mode < 3; ++mode)
			for (int cold = 0; cold < 2; ++cold)
				modes[2 * mode + cold] = time_mode(sample, frames, mode, cold != 0, repeats);
		report("acl", clip, frames, joints, file.size(), file.size() + sizeof(context), median(opens), modes);
		std::free(memory);
		return checksum == checksum ? 0 : 1;
	}
}

int main(int argc, char** argv)
{
	if (argc < 2)
	{
		std::fprintf(stderr, "usage: %s MANIFEST [REPEATS]\n", argv[0]);
		return 2;
	}
	const int repeats = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
	FILE* manifest = std::fopen(argv[1], "r");
	if (!manifest)
	{
		std::fprintf(stderr, "cannot read %s\n", argv[1]);
		return 2;
	}
	char mcb[4096], acl_path[4096];
	int failures = 0;
	while (std::fscanf(manifest, "%4095s %4095s", mcb, acl_path) == 2)
	{
		failures += bench_mcbrot(mcb, repeats);
		failures += bench_acl(acl_path, mcb, repeats);
	}
	std::fclose(manifest);
	return failures ? 1 : 0;
}
