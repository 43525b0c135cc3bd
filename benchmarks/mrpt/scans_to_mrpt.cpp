// scans_to_mrpt: a text file of laser scans -> the MRPT file the peers read, one of:
// - rawlog:    an "actions-observations" (SensFrame) rawlog, what rbpf-slam, icp-slam and
//              pf-localization read: per scan one CActionCollection (a CActionRobotMovement2D
//              with the odometry increment) followed by one CSensoryFrame (the scan);
// - simplemap: a CSimpleMap, the scans at given poses, from which pf-localization builds the
//              map it localises in.
//
// Built by benchmarks/mrpt_peers.py against libmrpt-obs-dev (MRPT 2.x). Usage:
//   scans_to_mrpt rawlog|simplemap scans.txt out-file
// Input, whitespace separated:
//   line 1:  beams aperture_rad sensor_yaw_rad max_range_m std_error_m a1 a2 a3 a4 min_std_xy
//            min_std_phi   (the odometry noise, MRPT's Gaussian motion model: std of x and y =
//            min_std_xy + a1 distance + a2 |turn|, of the heading = min_std_phi + a3 distance +
//            a4 |turn|, SI units; a simplemap ignores it)
//   then one line per scan:  stamp_s x y theta r_0 .. r_{beams-1}
// where (x, y, theta) is, for a rawlog, the odometry increment since the previous scan in the
// previous scan's frame, and for a simplemap the scan's pose in the map frame. Ranges go right
// to left, beam i at sensor_yaw - aperture/2 + i aperture/(beams-1) in the robot's frame (MRPT
// spreads the beams over the aperture from the first to the last, so a fan not centred on the
// robot's heading, e.g. 180 beams from -90 to +89 degrees, needs the sensor turned), and a range
// <= 0 marks a no-return reading (stored as invalid).
// The motion model is MRPT's Gaussian one, not Thrun's: a rawlog keeps the raw increment and
// the model, and the reader recomputes the distribution; Thrun's model is a set of random
// samples whose mean (what the SLAM apps use as odometry) is then off by a random amount, and
// icp-slam does not seed its generator, so its runs differed (aces: 0.48 to 2.7 m).
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

using namespace mrpt::obs;

struct Scanner
{
	size_t beams = 0;
	double aperture = 0, sensorYaw = 0, maxRange = 0, stdError = 0;

	CObservation2DRangeScan::Ptr scan(const std::vector<double>& ranges, mrpt::Clock::time_point when) const
	{
		auto scan = CObservation2DRangeScan::Create();
		scan->sensorLabel = "LASER";
		scan->timestamp = when;
		scan->aperture = static_cast<float>(aperture);
		scan->rightToLeft = true;
		scan->maxRange = static_cast<float>(maxRange);
		scan->stdError = static_cast<float>(stdError);
		scan->sensorPose = mrpt::poses::CPose3D(0, 0, 0, sensorYaw, 0, 0);
		scan->resizeScan(beams);
		for (size_t i = 0; i < beams; i++)
		{
			const bool valid = ranges[i] > 0 && ranges[i] < maxRange;
			scan->setScanRange(i, static_cast<float>(valid ? ranges[i] : maxRange));
			scan->setScanRangeValidity(i, valid);
		}
		return scan;
	}
};

int main(int argc, char** argv)
{
	const std::string kind = argc == 4 ? argv[1] : "";
	if (kind != "rawlog" && kind != "simplemap")
	{
		std::cerr << "usage: " << argv[0] << " rawlog|simplemap scans.txt out-file\n";
		return 2;
	}
	std::ifstream in(argv[2]);
	Scanner scanner;
	double a1 = 0, a2 = 0, a3 = 0, a4 = 0, minStdXY = 0, minStdPhi = 0;
	if (!(in >> scanner.beams >> scanner.aperture >> scanner.sensorYaw >> scanner.maxRange >> scanner.stdError >>
		  a1 >> a2 >> a3 >> a4 >> minStdXY >> minStdPhi) ||
		scanner.beams < 2)
	{
		std::cerr << argv[2] << ": bad header\n";
		return 1;
	}
	CActionRobotMovement2D::TMotionModelOptions motion;
	motion.modelSelection = CActionRobotMovement2D::mmGaussian;
	motion.gaussianModel = {a1, a2, a3, a4, minStdXY, minStdPhi};

	mrpt::io::CFileGZOutputStream out(argv[3]);
	auto archive = mrpt::serialization::archiveFrom(out);
	mrpt::maps::CSimpleMap map;
	std::vector<double> ranges(scanner.beams);
	double stamp, x, y, theta;
	size_t count = 0;
	while (in >> stamp >> x >> y >> theta)
	{
		for (auto& r : ranges)
			if (!(in >> r))
			{
				std::cerr << argv[2] << ": scan " << count << " is short\n";
				return 1;
			}
		const auto when = mrpt::Clock::fromDouble(stamp);
		auto frame = CSensoryFrame::Create();
		frame->insert(scanner.scan(ranges, when));
		if (kind == "rawlog")
		{
			CActionRobotMovement2D move;
			move.timestamp = when;
			move.computeFromOdometry(mrpt::poses::CPose2D(x, y, theta), motion);
			CActionCollection actions;
			actions.insert(move);
			archive << actions << *frame;
		}
		else
		{
			map.insert(mrpt::poses::CPose3DPDFGaussian(mrpt::poses::CPose3D(x, y, 0, theta, 0, 0)), *frame);
		}
		count++;
	}
	if (kind == "simplemap") archive << map;
	std::printf("%zu\n", count);
	return count ? 0 : 1;
}
